"""Writing a flight's report: trajectory CSV, TRN fix log, track and error plots.

- ``trajectory.csv``: at the log rate, truth and both solutions (latitude/longitude in
  degrees, north/east metres in the DEM's local frame, height), horizontal errors and the
  filters' 1-sigma north/east position uncertainty;
- ``trn_fixes.csv``: every TRN attempt with its outcome and reason;
- ``track.png``: hillshaded terrain (elevation colour bar) with the truth, INS-only and
  INS+TRN tracks, start/end markers, arrows giving the direction of flight, the accepted /
  rejected fixes (the rejected count is the summary's ``fixes_rejected``: every attempt not
  applied, whether or not it produced a position to plot) and a zoomed inset around the end
  of the flight, where the metre-level errors are visible;
- ``errors.png``: horizontal error (m) against time since GPS loss (s) with each filter's
  3-sigma bound (3 sqrt(lambda_max) of the 2x2 horizontal position covariance) and the
  applied TRN fixes as vertical lines (named in the legend).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from navgate.nav.earth import LocalTangent


def _tangent(result):
    return LocalTangent(*result.dem.center, 0.0)


def truth_rows(result) -> np.ndarray:
    """Per solution row, the truth row it is scored against, -1 where none: a replay's
    matched truth records (``result.truth_index``), else fly's sampling (every
    ``log_every``-th truth sample, the last one for the final row)."""
    idx = getattr(result, "truth_index", None)
    if idx is not None:
        return np.asarray(idx, np.int64)
    n = next(iter(result.runs.values())).t.size
    return np.minimum(np.arange(n) * result.log_every, len(result.data.truth) - 1)


def truth_track_rows(result) -> slice:
    """The truth rows the track plot draws: one a log row (fly's truth is per IMU sample, so
    every ``log_every``-th; a replay's truth records are at the log rate already, its
    ``log_every`` 1)."""
    return slice(None, None, max(1, int(result.log_every)))


def write_trajectory_csv(result, path: Path) -> Path:
    """One row a solution; a solution without truth (a replay's log with gaps) has its
    solution time as ``t_s`` and ``nan`` truth and error columns."""
    truth = result.data.truth
    tan = _tangent(result)
    idx = truth_rows(result)
    has = idx >= 0
    j = np.where(has, idx, 0)

    def at(values):
        return np.where(has, np.asarray(values)[j], np.nan)

    tn, te = tan.to_ned(at(truth.lat), at(truth.lon))
    cols = {
        "t_s": np.where(has, truth.t[j], next(iter(result.runs.values())).t),
        "truth_lat_deg": np.degrees(at(truth.lat)), "truth_lon_deg": np.degrees(at(truth.lon)),
        "truth_h_m": at(truth.h), "truth_north_m": tn, "truth_east_m": te,
    }
    for name, run in result.runs.items():
        n, e = tan.to_ned(run.nav[:, 0], run.nav[:, 1])
        cols[f"{name}_lat_deg"] = np.degrees(run.nav[:, 0])
        cols[f"{name}_lon_deg"] = np.degrees(run.nav[:, 1])
        cols[f"{name}_h_m"] = run.nav[:, 2]
        cols[f"{name}_north_m"] = n
        cols[f"{name}_east_m"] = e
        cols[f"{name}_horizontal_error_m"] = result.scores[name].horizontal_error
        cols[f"{name}_sigma_north_m"] = run.sigma[:, 0]
        cols[f"{name}_sigma_east_m"] = run.sigma[:, 1]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols.keys())
        for row in zip(*cols.values(), strict=True):
            w.writerow([f"{v:.9g}" for v in row])
    return path


def write_fixes_csv(result, path: Path) -> Path:
    run = result.runs.get("trn_aided")
    rows = run.fixes if run is not None else []
    keys = ["time_s", "lag_s", "applied", "reason", "nis", "shift_north_m", "shift_east_m",
            "sigma_north_m", "sigma_east_m", "fix_north_m", "fix_east_m", "msd_best_m2",
            "ambiguity_ratio", "roughness_m", "search_half_width_m", "samples"]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r.get(k), float) else r.get(k))
                        for k in keys})
    return path


def horizontal_sigma_bound(run, k=3.0):
    """k * sqrt(largest eigenvalue) of the 2x2 horizontal position covariance."""
    a = run.sigma[:, 0] ** 2
    c = run.sigma[:, 1] ** 2
    b = run.p_ne
    lam = 0.5 * (a + c) + np.sqrt(np.maximum(0.25 * (a - c) ** 2 + b**2, 0.0))
    return k * np.sqrt(lam)


def plot_track(result, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dem = result.dem
    tan = _tangent(result)
    shade = dem.hillshade()
    north_top, east_left = tan.to_ned(dem.lat_north, dem.lon_west)
    north_bottom, east_right = tan.to_ned(dem.lat_south, dem.lon_east)
    extent = [east_left / 1000, east_right / 1000, north_bottom / 1000, north_top / 1000]
    fig, ax = plt.subplots(figsize=(10, 8.5), dpi=110)
    terrain = ax.imshow(dem.heights, cmap="terrain", extent=extent, origin="upper", alpha=0.85)
    ax.imshow(shade, cmap="gray", extent=extent, origin="upper", alpha=0.35)
    fig.colorbar(terrain, ax=ax, shrink=0.8, label="terrain elevation (m)")
    truth = result.data.truth
    rows = truth_track_rows(result)
    tn, te = tan.to_ned(truth.lat[rows], truth.lon[rows])
    tracks = [(te / 1000, tn / 1000, "k", "truth", 2.0)]
    styles = {"ins_only": ("tab:red", "INS only"), "trn_aided": ("tab:blue", "INS + TRN")}
    for name, run in result.runs.items():
        n, e = tan.to_ned(run.nav[:, 0], run.nav[:, 1])
        color, label = styles.get(name, ("tab:gray", name))
        tracks.append((e / 1000, n / 1000, color, label, 1.4))
    fixes = []
    run = result.runs.get("trn_aided")
    if run is not None:
        acc = [f for f in run.fixes if f["applied"]]
        rej_all = [f for f in run.fixes if not f["applied"]]
        rej = [f for f in rej_all if math.isfinite(f["fix_north_m"])]
        if acc:
            fixes.append(([f["fix_east_m"] / 1000 for f in acc],
                          [f["fix_north_m"] / 1000 for f in acc],
                          dict(marker="o", ms=4, mfc="white", mec="tab:green", ls="none"),
                          f"TRN fix accepted ({len(acc)})"))
        if rej:  # a legend entry only where there are markers to show
            fixes.append(([f["fix_east_m"] / 1000 for f in rej],
                          [f["fix_north_m"] / 1000 for f in rej],
                          dict(marker="x", ms=6, color="tab:orange", ls="none"),
                          f"TRN fix rejected ({len(rej_all)}; {len(rej)} with a position)"))

    def draw(axis, legend: bool):
        for x, y, color, label, lw in tracks:
            axis.plot(x, y, "-", color=color, lw=lw, label=label if legend else None)
        for x, y, style, label in fixes:
            axis.plot(x, y, label=label if legend else None, **style)

    draw(ax, True)
    x, y = tracks[0][0], tracks[0][1]
    ax.plot(x[0], y[0], "^", ms=10, color="white", mec="k", label="start", zorder=5)
    ax.plot(x[-1], y[-1], "s", ms=9, color="white", mec="k", label="end (truth)", zorder=5)
    for k in np.linspace(0, x.size - 2, 8, dtype=int)[1:-1]:  # direction of flight
        ax.annotate("", xy=(x[k + 1], y[k + 1]), xytext=(x[k], y[k]),
                    arrowprops=dict(arrowstyle="-|>", color="k", lw=1.2, mutation_scale=15))
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    unplotted = len(rej_all) - len(rej) if run is not None else 0
    ax.set_title(f"GPS-denied flight over {dem.name}" + (
        f"\n({unplotted} rejected TRN attempt{'s' if unplotted != 1 else ''} without a "
        "position, not plotted)" if unplotted and not rej else ""))
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    # zoomed inset around the end of the flight: every solution's final position in view
    ends_x = [t[0][-1] for t in tracks]
    ends_y = [t[1][-1] for t in tracks]
    half = max(0.05, 1.3 * max(max(ends_x) - min(ends_x), max(ends_y) - min(ends_y)) / 2)
    cx, cy = (max(ends_x) + min(ends_x)) / 2, (max(ends_y) + min(ends_y)) / 2
    inset = ax.inset_axes([0.02, 0.02, 0.34, 0.34])
    inset.imshow(shade, cmap="gray", extent=extent, origin="upper", alpha=0.35)
    draw(inset, False)
    for ex, ey, (_, _, color, _, _) in zip(ends_x, ends_y, tracks, strict=True):
        inset.plot(ex, ey, "s", ms=6, color=color)
    inset.set_xlim(cx - half, cx + half)
    inset.set_ylim(cy - half, cy + half)
    inset.set_aspect("equal")
    inset.set_title(f"end of flight, {2000 * half:.0f} m wide", fontsize=7)
    inset.set_xlabel("east (km)", fontsize=6, labelpad=1)
    inset.set_ylabel("north (km)", fontsize=6, labelpad=1)
    inset.tick_params(labelsize=6)
    ax.indicate_inset_zoom(inset, edgecolor="0.3")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_errors(result, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"ins_only": ("tab:red", "INS only"), "trn_aided": ("tab:blue", "INS + TRN")}
    fig, axes = plt.subplots(len(result.runs), 1, figsize=(9, 3.2 * len(result.runs)), dpi=110,
                             squeeze=False)
    for ax, (name, run) in zip(axes[:, 0], result.runs.items(), strict=True):
        color, label = styles.get(name, ("tab:gray", name))
        err = result.scores[name].horizontal_error
        ax.plot(run.t, err, color=color, lw=1.2, label=f"{label}: horizontal error")
        ax.plot(run.t, horizontal_sigma_bound(run), "k--", lw=1.0, label="filter 3-sigma")
        if name == "trn_aided":
            applied = [f["time_s"] for f in run.fixes if f["applied"]]
            for i, t_fix in enumerate(applied):
                ax.axvline(t_fix, color="tab:green", lw=0.4, alpha=0.5,
                           label=f"TRN fix applied ({len(applied)})" if i == 0 else None)
        if name == "ins_only":
            ax.text(0.99, 0.97, "the INS-only error can fall in turns: the barometer then "
                    "observes tilt,\nwhich is correlated with position "
                    "(docs/seed000-navigator.md, section 6)", transform=ax.transAxes,
                    ha="right", va="top", fontsize=7, color="0.35")
        ax.set_ylabel("horizontal position error (m)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    axes[-1, 0].set_xlabel("time since GPS loss (s)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def write_report(result, out_dir: Path) -> dict:
    """Write every report file; returns name -> path."""
    out_dir = Path(out_dir)
    return {
        "trajectory_csv": write_trajectory_csv(result, out_dir / "trajectory.csv"),
        "fixes_csv": write_fixes_csv(result, out_dir / "trn_fixes.csv"),
        "track_png": plot_track(result, out_dir / "track.png"),
        "errors_png": plot_errors(result, out_dir / "errors.png"),
    }
