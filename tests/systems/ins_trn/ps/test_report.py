"""The flight report's plots (issue 31, everyday use): the track's zoom has axis labels, no
legend entry without markers, and errors.png explains the INS-only error falling in turns."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from navgate.nav.earth import LocalTangent
from navgate.systems.ins_trn.ps import report
from navgate.trn.dem import Dem


@pytest.fixture
def figures(monkeypatch):
    """The figures the report closes, in order (the plots are inspected, not just saved)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    closed = []
    real_close = plt.close

    def close(fig=None):
        closed.append(fig)
        real_close(fig)

    monkeypatch.setattr(plt, "close", close)
    return closed


def _result(fixes):
    dem = Dem.default()
    tan = LocalTangent(*dem.center, 0.0)
    n = 50
    t = np.arange(n) * 0.1
    north, east = np.linspace(-500, 500, n), np.linspace(-300, 300, n)
    lat, lon = tan.to_geodetic(north, east)
    truth = SimpleNamespace(t=t, lat=np.asarray(lat), lon=np.asarray(lon), h=np.full(n, 900.0))

    def run(offset, fx):
        nav = np.zeros((n, 10))
        nav[:, 0], nav[:, 1] = truth.lat + offset, truth.lon
        nav[:, 2] = 900.0
        return SimpleNamespace(t=t, nav=nav, sigma=np.full((n, 2), 5.0), p_ne=np.zeros(n),
                               fixes=fx)

    runs = {"ins_only": run(1e-6, []), "trn_aided": run(2e-7, fixes)}
    scores = {k: SimpleNamespace(horizontal_error=np.full(n, 3.0)) for k in runs}
    return SimpleNamespace(dem=dem, runs=runs, data=SimpleNamespace(truth=truth),
                           scores=scores, log_every=1)


def _labels(ax):
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend else []


def test_track_zoom_labels_and_no_empty_legend_entry(figures, tmp_path):
    nan = float("nan")
    fixes = [{"applied": True, "fix_north_m": 10.0, "fix_east_m": 5.0, "time_s": 1.0},
             {"applied": False, "fix_north_m": nan, "fix_east_m": nan, "time_s": 2.0},
             {"applied": False, "fix_north_m": nan, "fix_east_m": nan, "time_s": 3.0}]
    report.plot_track(_result(fixes), tmp_path / "track.png")
    fig = figures[-1]
    main = fig.axes[0]
    inset = next(ax for ax in [*fig.axes, *main.child_axes]
                 if ax.get_title().startswith("end of flight"))
    assert inset.get_xlabel() == "east (km)" and inset.get_ylabel() == "north (km)"
    labels = _labels(main)
    assert "TRN fix accepted (1)" in labels
    assert not any("rejected" in label for label in labels), labels  # no markers: no entry
    assert "2 rejected TRN attempts without a position" in main.get_title()
    # with a rejected fix that has a position, the entry is back (with its marker)
    fixes[1].update(fix_north_m=20.0, fix_east_m=1.0)
    report.plot_track(_result(fixes), tmp_path / "track.png")
    labels = _labels(figures[-1].axes[0])
    assert "TRN fix rejected (2; 1 with a position)" in labels
    assert "without a position" not in figures[-1].axes[0].get_title()


def test_errors_plot_explains_ins_only_falls_in_turns(figures, tmp_path):
    report.plot_errors(_result([]), tmp_path / "errors.png")
    ins_ax, trn_ax = figures[-1].axes[:2]
    notes = [t.get_text() for t in ins_ax.texts]
    assert any("fall in turns" in n and "seed000-navigator.md" in n for n in notes), notes
    assert not trn_ax.texts


def test_track_draws_the_truth_once_a_log_row(figures, tmp_path):
    """The truth track takes one point a log row: fly's truth is per IMU sample (every
    ``log_every``-th), a replay's truth records are at the log rate (``log_every`` 1; the
    plot used to take every 40th row of them, one point in 4 s)."""
    for log_every, points in ((1, 50), (10, 5)):
        result = _result([])
        result.log_every = log_every
        report.plot_track(result, tmp_path / "track.png")
        main = figures[-1].axes[0]
        truth = [line for line in main.get_lines() if line.get_label() == "truth"]
        assert len(truth) == 1 and len(truth[0].get_xdata()) == points
