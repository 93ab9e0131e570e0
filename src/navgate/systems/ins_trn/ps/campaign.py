"""Monte Carlo campaigns of the seed-000 flight: seeds x terrains x options, run on Dask.

Every run is one :func:`navgate.systems.ins_trn.ps.flight.fly` (the same scenario, sensors and
navigation as ``navgate fly``: INS-only and INS+TRN on the same sensor data) for one
(DEM, TRN method, ranger, seed). Runs are independent tasks on a ``dask.distributed``
cluster: a :class:`~distributed.LocalCluster` of ``workers`` single-threaded processes by
default, or an existing scheduler by address (each of its workers needs navgate
importable). A run that raises is kept as a failed run with its seed and error message;
nothing is dropped.

Statistics per configuration (docs/trn.md, "Campaigns"):

- RMS: per run, the RMS horizontal error over the second half of the flight (mean and
  worst over the runs) and over the whole flight;
- CEP50 / CEP95: the 50 % / 95 % quantiles of the horizontal error, all logged samples of
  all runs of the configuration pooled (the whole flight);
- final error (INS+TRN and INS-only), and the number of runs in which INS+TRN ends worse
  than INS-only;
- time to the first applied TRN fix (mean over the runs that had one; runs without one are
  counted);
- NEES: per run the time average of the 2-dof horizontal-position NEES, then the mean over
  the runs, with its 95 % band: for N runs of a consistent filter the sum of N per-time
  NEES values is chi-square with 2N dof, so the mean lies in
  [chi2.ppf(0.025, 2N) / N, chi2.ppf(0.975, 2N) / N] (Bar-Shalom, Li & Kirubarajan 2001,
  sec. 5.4.2);
- the fraction of logged samples whose horizontal error exceeds the filter's 3-sigma bound
  3 sqrt(lambda_max(P_NE)) (the bound drawn in ``navgate fly``'s errors.png).
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import logging
import math
import time as _time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: per-run fields written to results.csv, in order
RESULT_FIELDS = [
    "dem", "trn", "ranger", "seed", "status", "error", "duration_s",
    "rms_second_half_m", "rms_m", "final_error_m", "max_error_m",
    "ins_only_final_error_m", "ins_only_rms_second_half_m", "trn_worse_than_ins_only",
    "time_to_first_fix_s", "fixes_applied", "fixes_attempted", "divergence_events",
    "nees_mean", "outside_3sigma_samples", "samples", "wall_s",
]


#: the most seeds one campaign takes, and the largest seed (NumPy's SeedSequence takes any
#: non-negative integer; the results table and summary.json store seeds as 64-bit integers)
MAX_SEEDS = 100_000
MAX_SEED = 2**63 - 1


def parse_seeds(text: str) -> list[int]:
    """'0-49', '3', '0,2,5-7' -> sorted list of distinct non-negative seeds.

    At most :data:`MAX_SEEDS` seeds, checked before any range is expanded (a range such as
    0-1180591620717411303424 is refused at once, not enumerated)."""
    seeds: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        if not part:
            raise ValueError(f"empty item in seed list {text!r}")
        if "-" in part[1:]:
            a, b = part.split("-", 1) if not part.startswith("-") else (part, "")
            try:
                lo, hi = int(a), int(b)
            except ValueError:
                raise ValueError(f"bad seed range {part!r} (expected A-B)") from None
            if lo < 0 or hi < lo:
                raise ValueError(f"bad seed range {part!r}")
            if hi - lo + 1 + len(seeds) > MAX_SEEDS:
                raise ValueError(f"more than {MAX_SEEDS} seeds ({part} alone is "
                                 f"{hi - lo + 1:,})")
            seeds.update(range(lo, hi + 1))
        else:
            try:
                s = int(part)
            except ValueError:
                raise ValueError(f"bad seed {part!r}") from None
            if s < 0:
                raise ValueError(f"seeds must be non-negative, got {s}")
            seeds.add(s)
    if len(seeds) > MAX_SEEDS:
        raise ValueError(f"more than {MAX_SEEDS} seeds")
    if max(seeds, default=0) > MAX_SEED:
        raise ValueError(f"seeds must be below 2**63, got {max(seeds)}")
    return sorted(seeds)


@dataclass(frozen=True)
class Configuration:
    dem: str  #: "default" or a DEM file path
    trn: str
    ranger: str = "long-range"

    def label(self) -> str:
        name = "default" if self.dem == "default" else Path(self.dem).name
        return f"{name} / {self.trn} / {self.ranger}"


@dataclass(frozen=True)
class Campaign:
    seeds: tuple
    configurations: tuple
    duration_s: float = 600.0
    imu_rate_hz: float = 400.0

    @classmethod
    def build(cls, seeds, dems, trns, rangers=("long-range",), duration_s=600.0,
              imu_rate_hz=400.0) -> Campaign:
        confs = tuple(Configuration(d, t, r) for d, t, r in itertools.product(dems, trns, rangers))
        return cls(tuple(seeds), confs, float(duration_s), float(imu_rate_hz))

    def tasks(self):
        return [(c, s) for c in self.configurations for s in self.seeds]


_DEM_CACHE: dict = {}


def _load_dem(spec: str):
    from navgate.trn.tiles import load_terrain

    if spec not in _DEM_CACHE:
        _DEM_CACHE[spec] = load_terrain(None if spec == "default" else spec)
    return _DEM_CACHE[spec]


def warm_worker() -> float:
    """Import navgate and compile (or load from the cache) the Numba kernels of a run in this
    process, so that the runs' wall times are the runs' own; returns the seconds it took."""
    start = _time.perf_counter()
    from navgate.systems.ins_trn.ps.flight import FlightConfig, fly
    from navgate.trn.pmf import PmfConfig, PointMassCorrelator
    from navgate.trn.profile import ProfileSnapshot
    from navgate.trn.tercom import TercomCorrelator

    dem = _load_dem("default")
    fly(dem, FlightConfig(duration_s=2.0))
    from navgate.nav.earth import LocalTangent

    tan = LocalTangent(*dem.center, 0.0)
    k = np.arange(40.0)
    snap = ProfileSnapshot(np.full(40, 500.0), 30.0 * k, np.zeros(40), 0.5 * k)
    PointMassCorrelator(dem, tan, PmfConfig()).correlate(snap, 10.0)
    TercomCorrelator(dem, tan).correlate(snap, 10.0)
    return _time.perf_counter() - start


def _sigma_bound(run, k=3.0):
    a = run.sigma[:, 0] ** 2
    c = run.sigma[:, 1] ** 2
    b = run.p_ne
    lam = 0.5 * (a + c) + np.sqrt(np.maximum(0.25 * (a - c) ** 2 + b**2, 0.0))
    return k * np.sqrt(lam)


def run_one(conf: Configuration, seed: int, duration_s: float, imu_rate_hz: float) -> dict:
    """One Monte Carlo run (a Dask task); never raises: failures come back as status 'failed'.

    Returns the results.csv row plus ``errors`` / ``nees`` (1 Hz samples for the pooled
    CEP and the NEES histogram).
    """
    start = _time.perf_counter()
    row = {"dem": conf.dem, "trn": conf.trn, "ranger": conf.ranger, "seed": int(seed),
           "status": "ok", "error": "", "duration_s": duration_s}
    try:
        from navgate.systems.ins_trn.ps.flight import FlightConfig, TrnSettings, fly

        dem = _load_dem(conf.dem)
        cfg = FlightConfig(duration_s=duration_s, imu_rate_hz=imu_rate_hz, seed=int(seed),
                           trn=True, ranger=conf.ranger)
        result = fly(dem, cfg, trn=TrnSettings(method=conf.trn))
        trn_run = result.runs["trn_aided"]
        ins_run = result.runs["ins_only"]
        st = result.scores["trn_aided"].summary(trn_run.t)
        si = result.scores["ins_only"].summary(ins_run.t)
        err = result.scores["trn_aided"].horizontal_error
        nees = result.scores["trn_aided"].nees
        bound = _sigma_bound(trn_run)
        applied = [f["time_s"] for f in trn_run.fixes if f["applied"]]
        t0 = float(trn_run.t[0])
        every = max(1, int(round(cfg.log_rate_hz)))
        row.update({
            "rms_second_half_m": st["rms_horizontal_error_second_half_m"],
            "rms_m": st["rms_horizontal_error_m"],
            "final_error_m": st["final_horizontal_error_m"],
            "max_error_m": st["max_horizontal_error_m"],
            "ins_only_final_error_m": si["final_horizontal_error_m"],
            "ins_only_rms_second_half_m": si["rms_horizontal_error_second_half_m"],
            "trn_worse_than_ins_only": bool(st["final_horizontal_error_m"]
                                            > si["final_horizontal_error_m"]),
            "time_to_first_fix_s": (min(applied) - t0) if applied else math.nan,
            "fixes_applied": len(applied),
            "fixes_attempted": len(trn_run.fixes),
            "divergence_events": sum(1 for f in trn_run.fixes if f.get("integrity")),
            "nees_mean": st["nees_position_mean"],
            "outside_3sigma_samples": int(np.count_nonzero(err > bound)),
            "samples": int(err.size),
            "errors": err[::every].astype(np.float32),
            "nees": nees[::every].astype(np.float32),
        })
    except Exception as error:  # a failed run is reported, never dropped
        row["status"] = "failed"
        row["error"] = f"{type(error).__name__}: {' '.join(str(error).split())}"
        row["traceback"] = traceback.format_exc(limit=6)
    row["wall_s"] = _time.perf_counter() - start
    return row


def _failed_row(conf, seed, duration_s, message):
    return {"dem": conf.dem, "trn": conf.trn, "ranger": conf.ranger, "seed": int(seed),
            "status": "failed", "error": message, "duration_s": duration_s,
            "wall_s": math.nan}


@dataclass
class CampaignResult:
    campaign: Campaign
    rows: list  #: one dict per run (results.csv rows, plus samples)
    wall_time_s: float
    workers: int
    scheduler: str
    configurations: list = field(default_factory=list)

    def summary(self) -> dict:
        ok_walls = [r["wall_s"] for r in self.rows
                    if r["status"] == "ok" and math.isfinite(r.get("wall_s", math.nan))]
        mean_wall = float(np.mean(ok_walls)) if ok_walls else math.nan
        ideal = mean_wall * len(self.rows) / max(self.workers, 1)
        return {
            "runs": len(self.rows),
            "failed": sum(r["status"] != "ok" for r in self.rows),
            "seeds": list(self.campaign.seeds),
            "duration_s": self.campaign.duration_s,
            "imu_rate_hz": self.campaign.imu_rate_hz,
            "workers": self.workers,
            "scheduler": self.scheduler,
            "wall_time_s": self.wall_time_s,
            "run_wall_s_mean": mean_wall,
            "run_wall_s_sum": float(np.sum(ok_walls)) if ok_walls else 0.0,
            #: campaign wall / (mean single-run wall x runs / workers); 1.0 = perfect scaling
            "scaling_ratio": self.wall_time_s / ideal if ideal > 0 else math.nan,
            "configurations": self.configurations,
            "failed_runs": [{"dem": r["dem"], "trn": r["trn"], "ranger": r["ranger"],
                             "seed": r["seed"], "error": r["error"]}
                            for r in self.rows if r["status"] != "ok"],
        }


def aggregate(conf: Configuration, rows: list) -> dict:
    """The per-configuration statistics (module docstring) of ``rows``."""
    from scipy.stats import chi2

    ok = [r for r in rows if r["status"] == "ok"]
    out = {"dem": conf.dem, "dem_name": "default" if conf.dem == "default"
           else Path(conf.dem).name, "trn": conf.trn, "ranger": conf.ranger,
           "label": conf.label(), "runs": len(rows), "failed": len(rows) - len(ok),
           "failed_seeds": sorted(r["seed"] for r in rows if r["status"] != "ok")}
    keys = ("rms_second_half_m_mean", "rms_second_half_m_max", "rms_m_mean", "cep50_m",
            "cep95_m", "final_error_m_mean", "final_error_m_max",
            "ins_only_final_error_m_mean", "ins_only_rms_second_half_m_mean",
            "runs_trn_worse_than_ins_only", "time_to_first_fix_s_mean",
            "time_to_first_fix_s_max", "runs_without_fix", "nees_mean", "nees_band_95",
            "nees_in_band", "outside_3sigma_fraction", "divergence_events")
    if not ok:
        out.update({k: None for k in keys})
        return out

    def col(name):
        return np.array([r[name] for r in ok], dtype=float)

    errors = np.concatenate([np.asarray(r["errors"], float) for r in ok])
    ttff = col("time_to_first_fix_s")
    n = len(ok)
    band = [float(chi2.ppf(0.025, 2 * n) / n), float(chi2.ppf(0.975, 2 * n) / n)]
    nees = float(np.nanmean(col("nees_mean")))
    samples = col("samples").sum()
    out.update({
        "rms_second_half_m_mean": float(np.mean(col("rms_second_half_m"))),
        "rms_second_half_m_max": float(np.max(col("rms_second_half_m"))),
        "rms_m_mean": float(np.mean(col("rms_m"))),
        "cep50_m": float(np.quantile(errors, 0.5)),
        "cep95_m": float(np.quantile(errors, 0.95)),
        "final_error_m_mean": float(np.mean(col("final_error_m"))),
        "final_error_m_max": float(np.max(col("final_error_m"))),
        "ins_only_final_error_m_mean": float(np.mean(col("ins_only_final_error_m"))),
        "ins_only_rms_second_half_m_mean": float(np.mean(col("ins_only_rms_second_half_m"))),
        "runs_trn_worse_than_ins_only": int(sum(bool(r["trn_worse_than_ins_only"])
                                                for r in ok)),
        "time_to_first_fix_s_mean": (float(np.nanmean(ttff)) if np.any(np.isfinite(ttff))
                                     else None),
        "time_to_first_fix_s_max": (float(np.nanmax(ttff)) if np.any(np.isfinite(ttff))
                                    else None),
        "runs_without_fix": int(np.count_nonzero(~np.isfinite(ttff))),
        "nees_mean": nees,
        "nees_band_95": band,
        "nees_in_band": bool(band[0] <= nees <= band[1]),
        "outside_3sigma_fraction": float(col("outside_3sigma_samples").sum() / samples)
        if samples else None,
        "divergence_events": int(col("divergence_events").sum()),
    })
    return out


#: Dask's loggers that report a normal shutdown as warnings ("Worker process still alive
#: after 3.9 seconds, killing", closed comms): silenced to errors while the cluster closes
_DASK_LOGGERS = ("distributed", "distributed.nanny", "distributed.core", "distributed.worker",
                 "distributed.scheduler", "distributed.comm", "distributed.batched",
                 "distributed.client")


@contextlib.contextmanager
def _quiet_dask_shutdown():
    """Within the block, Dask's loggers pass errors only (their warnings at the end of a
    normal run say nothing to a user; a failed run is reported through its row)."""
    loggers = [logging.getLogger(name) for name in _DASK_LOGGERS]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def run_campaign(campaign: Campaign, *, workers: int = 2, scheduler: str | None = None,
                 progress=None) -> CampaignResult:
    """Run every (configuration, seed) on Dask; ``progress(row)`` after each run."""
    from dask.distributed import Client, LocalCluster, as_completed

    start = _time.perf_counter()
    cluster = None
    if scheduler:
        client = Client(scheduler, timeout="30s")
        n_workers = len(client.scheduler_info().get("workers", {})) or workers
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=50)
        client = Client(cluster)
        n_workers = workers
    rows = []
    try:
        client.run(warm_worker)
        tasks = campaign.tasks()
        futures = {}
        for conf, seed in tasks:
            fut = client.submit(run_one, conf, seed, campaign.duration_s, campaign.imu_rate_hz,
                                pure=False, key=f"run-{conf.dem}-{conf.trn}-{conf.ranger}-{seed}")
            futures[fut] = (conf, seed)
        for fut in as_completed(futures):
            conf, seed = futures[fut]
            try:
                row = fut.result()
            except Exception as error:  # the worker died or the task could not run
                row = _failed_row(conf, seed, campaign.duration_s,
                                  f"{type(error).__name__}: {' '.join(str(error).split())}")
            rows.append(row)
            if progress is not None:
                progress(row)
    finally:
        with _quiet_dask_shutdown():
            client.close()
            if cluster is not None:
                cluster.close()
    order = {(c, s): i for i, (c, s) in enumerate(campaign.tasks())}
    rows.sort(key=lambda r: order.get((Configuration(r["dem"], r["trn"], r["ranger"]),
                                       r["seed"]), 0))
    result = CampaignResult(campaign, rows, _time.perf_counter() - start, n_workers,
                            scheduler or "LocalCluster")
    result.configurations = [
        aggregate(c, [r for r in rows if (r["dem"], r["trn"], r["ranger"]) ==
                      (c.dem, c.trn, c.ranger)])
        for c in campaign.configurations]
    return result


# -- report -----------------------------------------------------------------------------------
def _csv_value(v):
    """A results.csv field: floats to 6 digits; no value (NaN: a run without a fix has no
    time to first fix, counted in the summary's runs_without_fix) is an empty field."""
    if isinstance(v, float):
        return f"{v:.6g}" if math.isfinite(v) else ""
    return v


def write_results_csv(result: CampaignResult, path: Path) -> Path:
    """One row a run (:data:`RESULT_FIELDS`); a value that does not exist is left empty."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=RESULT_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in result.rows:
            w.writerow({k: _csv_value(r.get(k, "")) for k in RESULT_FIELDS})
    return path


def plot_error_cdf(result: CampaignResult, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    for conf in result.configurations:
        rows = [r for r in result.rows if r["status"] == "ok"
                and (r["dem"], r["trn"], r["ranger"]) == (conf["dem"], conf["trn"],
                                                          conf["ranger"])]
        if not rows:
            continue
        e = np.sort(np.concatenate([np.asarray(r["errors"], float) for r in rows]))
        ax.plot(e, np.arange(1, e.size + 1) / e.size, label=f"{conf['label']} ({len(rows)} runs)")
    ax.set_xscale("log")
    ax.set_xlabel("horizontal error (m), INS + TRN, all samples")
    ax.set_ylabel("cumulative fraction")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_nees_hist(result: CampaignResult, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    bins = np.linspace(0, 15, 61)
    for conf in result.configurations:
        rows = [r for r in result.rows if r["status"] == "ok"
                and (r["dem"], r["trn"], r["ranger"]) == (conf["dem"], conf["trn"],
                                                          conf["ranger"])]
        if not rows:
            continue
        nees = np.concatenate([np.asarray(r["nees"], float) for r in rows])
        nees = nees[np.isfinite(nees)]
        ax.hist(np.minimum(nees, bins[-1]), bins=bins, density=True, histtype="step",
                label=f"{conf['label']}")
    x = np.linspace(0.05, 15, 300)
    ax.plot(x, 0.5 * np.exp(-0.5 * x), "k--", label="chi-square, 2 dof")
    ax.set_xlabel("horizontal position NEES (values above 15 in the last bin)")
    ax.set_ylabel("density")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def write_report(result: CampaignResult, out_dir: Path) -> dict:
    out_dir = Path(out_dir)
    return {
        "results_csv": write_results_csv(result, out_dir / "results.csv"),
        "error_cdf_png": plot_error_cdf(result, out_dir / "error_cdf.png"),
        "nees_hist_png": plot_nees_hist(result, out_dir / "nees_hist.png"),
    }
