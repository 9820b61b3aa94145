"""Trustworthy figures and reports: WV band check, legends, Allan markers, timeline labels, HTML numbers."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

import imunoise.noise.plots as plots
from imunoise.errors import DataError
from imunoise.noise.allan import BI_FACTOR, allan_fit, allan_variance, plot_allan, read_allan
from imunoise.noise.estimator import band_departures, departures_text, gmwm
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN
from imunoise.noise.wv import WaveletVariance
from imunoise.report import Report, nobreak_numbers

TRUTH = AR1(phi=0.999, sigma2=4e-6) + WN(sigma2=1e-4)


@pytest.fixture(scope="module")
def data():
    return TRUTH.simulate(2**16, seed=11)


@pytest.fixture
def keep_figures(monkeypatch):
    """The figures the plotting functions close, kept open for inspection."""
    figs, close = [], plt.close
    monkeypatch.setattr(plots.plt, "close", lambda fig=None: figs.append(fig))
    yield figs
    for f in figs:
        close(f)


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def _toy_wv(freq: float = 10.0) -> WaveletVariance:
    n = 6
    return WaveletVariance(
        scales=2.0 ** np.arange(1, n + 1), variance=np.ones(n), ci_low=np.full(n, 0.5), ci_high=np.full(n, 2.0),
        n_coefficients=np.full(n, 100), cov=np.eye(n) * 0.01, freq=freq,
    )


def test_band_departures_exact_runs():
    wv = _toy_wv(freq=10.0)  # τ = 0.2, 0.4, 0.8, 1.6, 3.2, 6.4 s
    nu = np.array([3.0, 3.0, 1.0, 0.1, 1.0, np.nan])  # out, out, in, out, in, NaN (out)
    assert band_departures(wv, nu, min_levels=1) == [(0.2, 0.4), (1.6, 1.6), (6.4, 6.4)]
    assert band_departures(wv, nu) == [(0.2, 0.4)]  # single levels are chance at 95 %
    assert band_departures(wv, np.ones(6)) == []
    assert band_departures(wv, np.array([0.5, 2.0, 1, 1, 1, 1])) == []  # the band's edges are inside
    assert departures_text([(0.2, 0.4), (1.6, 1.6)]) == "0.2–0.4 s, 1.6 s"
    with pytest.raises(DataError, match="levels"):
        band_departures(wv, np.ones(5))


def test_band_check_flags_wrong_model_not_right_one(data):
    right = gmwm(TRUTH.unknown(), data, freq=100.0, unit="rad/s")
    wrong = gmwm(Model.parse("WN"), data, freq=100.0, unit="rad/s")
    tau = right.wv.scales / right.wv.freq
    n_right = sum(int(np.sum((tau >= a) & (tau <= b))) for a, b in band_departures(right.wv, right.theoretical_wv))
    assert n_right <= 2, band_departures(right.wv, right.theoretical_wv)
    assert ("outside the 95% WV band" in right.summary()) == (n_right > 0)
    bad = band_departures(wrong.wv, wrong.theoretical_wv)
    # WN alone cannot follow the AR1's bump (T_c = 10 s): long runs of levels leave the band
    n_wrong = sum(int(np.sum((tau >= a) & (tau <= b))) for a, b in bad)
    assert n_wrong >= 5
    assert any(a <= 10.0 <= b for a, b in bad)
    assert f"fit outside the 95% WV band at τ = {departures_text(bad)}" in wrong.summary()


def test_summary_says_no_ci_for_av_and_not_identified_only_when_so(data):
    av = allan_fit(data, freq=100.0, unit="rad/s")
    text = av.summary()
    assert "no CI" in text and "(not identified)" not in text
    fit = gmwm(TRUTH.unknown(), data, freq=100.0, unit="rad/s")
    assert "(not identified)" not in fit.summary() and "no CI" not in fit.summary()
    # an infinite variance (what _param_cov gives a pinned parameter) is "not identified", for that one only
    cov = fit.param_cov_u.copy()
    k = fit.model.param_names.index("WN.sigma2")
    cov[k, :] = cov[:, k] = 0.0
    cov[k, k] = np.inf
    fit.param_cov_u = cov
    rows = {line.split()[0]: line for line in fit.summary().splitlines()[3:] if line.strip()}
    assert "(not identified)" in rows["WN.sigma2"] and "(not identified)" in rows["WN.noise_density"]
    assert "(not identified)" not in rows["AR1_1.phi"]


def test_wv_fit_plot_drops_offscale_curves_and_flags_band(data, keep_figures, tmp_path):
    # the RW is 30 decades below the data: drawn, but no legend entry, named in the corner note
    model = TRUTH + RW(gamma2=1e-40)
    fit = gmwm(model.unknown(), data, freq=100.0, unit="rad/s")
    fit.model = fit.model.with_params({**fit.params, "RW.gamma2": 1e-40})
    plots.plot_wv_fit(fit, tmp_path / "wv.png")
    texts = _legend_texts(keep_figures[0])
    assert "RW" not in texts and "WN" in texts and "AR1_1" in texts
    notes = [t.get_text() for t in keep_figures[0].axes[0].texts]
    assert notes == ["not in view:\nRW\u00a0(below)"]
    wrong = gmwm(Model.parse("WN"), data, freq=100.0, unit="rad/s")
    plots.plot_wv_fit(wrong, tmp_path / "wrong.png")
    assert any(t.startswith("fit outside the 95% band") for t in _legend_texts(keep_figures[1]))
    assert (tmp_path / "wv.png").stat().st_size > 10_000


def test_wv_fits_method_colours_and_band_text(data, keep_figures, tmp_path):
    right = gmwm(TRUTH.unknown(), data, freq=100.0, unit="rad/s")
    wrong = gmwm(Model.parse("WN"), data, freq=100.0, unit="rad/s")
    plots.plot_wv_fits(right.wv, [("GMWM: right", right.theoretical_wv), ("AV: wrong", wrong.theoretical_wv)],
                       tmp_path / "cmp.png", unit="rad/s")
    ax = keep_figures[0].axes[0]
    lines = {ln.get_label().split(":")[0]: ln for ln in ax.get_lines()}
    assert lines["GMWM"].get_color() == plots.METHOD_COLORS["gmwm"]
    assert lines["AV"].get_color() == plots.METHOD_COLORS["av"]
    assert "outside the band" in lines["AV"].get_label()


def test_allan_plot_units_b_marker_and_colours(keep_figures, tmp_path):
    x = (AR1(phi=0.999, sigma2=1e-6) + WN(sigma2=1e-4) + RW(gamma2=1e-12)).simulate(2**17, seed=3)
    av = allan_variance(x, freq=100.0)
    reading = read_allan(av)
    assert "N" in reading.lines and "B" in reading.lines
    plot_allan(av, tmp_path / "av.png", reading=reading, unit="rad/s",
               models=[("GMWM: m", TRUTH), ("AV: m", TRUTH)])
    ax = keep_figures[0].axes[0]
    texts = _legend_texts(keep_figures[0])
    assert any(t.startswith("N = ") and "rad/s/√Hz" in t for t in texts)
    by_label = {ln.get_label(): ln for ln in ax.get_lines()}
    b = next(ln for lab, ln in by_label.items() if lab.startswith("B = "))
    assert b.get_ydata()[0] == pytest.approx(reading.B)  # the B square sits at B, not at the AD minimum
    assert b.get_xdata()[0] == pytest.approx(reading.T_BI)
    amin = by_label["AD minimum = 0.6643·B"]
    assert amin.get_ydata()[0] == pytest.approx(BI_FACTOR * reading.B)
    ieee = {ln.get_color() for lab, ln in by_label.items() if lab[:1] in "NKQRB" and "=" in lab}
    assert by_label["GMWM: m"].get_color() == plots.METHOD_COLORS["gmwm"]
    assert not ieee & set(plots.METHOD_COLORS.values())


def test_timeline_labels_do_not_overlap():
    from imunoise.experiments.plots import _stagger_labels

    fig, ax = plt.subplots(figsize=(11, 3))
    ax.plot([0, 550], [0, 0])
    ax.set_ylim(-1, 2.5)
    _stagger_labels(ax, [(27.0, "5.3 s"), (33.1, "0.15 s"), (30.0, "0.2 s"), (204.7, "0.14 s")],
                    rows=(-0.38, -0.62, -0.86))
    r = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(r) for t in ax.texts]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), (ax.texts[i].get_text(), ax.texts[j].get_text())
    assert {t.get_position()[0] for t in ax.texts} == {27.0, 33.1, 30.0, 204.7}  # each under its point
    plt.close(fig)


def test_report_numbers_never_break_and_log_wraps(tmp_path):
    assert nobreak_numbers("σ 1.5e-05 at 21–32 s, it&#x27;s #1") == (
        "σ <span class='n'>1.5e-05</span> at <span class='n'>21–32 s</span>, it&#x27;s #1"
    )
    assert nobreak_numbers("N true [u/√Hz]") == "N true <span class='n'>[u/√Hz]</span>"
    rep = Report("t").table(["a", "b"], [["x", 1.5e-5], ["0.1/0.2/0.3", "AR1 + WN"], ["plain (LC model)", "–"]])
    rep.log(['{"t": 243284.717, "event": "identified"}'])
    html = rep.html()
    assert "<td class='num'>1.500e-05</td>" in html and "<td class='num'>0.1/0.2/0.3</td>" in html
    assert "<td class='num'>AR1 + WN</td>" in html  # a model structure does not wrap
    assert "<td>plain (LC model)</td>" in html  # text cells may wrap
    assert ".n,td.num{white-space:nowrap}" in html
    assert "<div class='log'><div>{&quot;t&quot;: <span class='n'>243284.717</span>" in html
    assert "```" in rep.markdown()


# -- the experiment reports' figures ---------------------------------------------------------------------
@pytest.fixture
def keep_experiment_figures(monkeypatch):
    """The figures imunoise.experiments.plots closes, kept open for inspection."""
    import imunoise.experiments.plots as eplots

    figs, close = [], plt.close
    monkeypatch.setattr(eplots.plt, "close", lambda fig=None: figs.append(fig))
    yield figs
    for f in figs:
        close(f)


def _paired(baseline: str, method: str, gnss: str, lo: float, ratio: float, hi: float) -> dict:
    return {"metric": "drift", "baseline": baseline, "method": method, "gnss": gnss, "ratio": ratio,
            "ci": [lo, hi], "significant": not lo <= 1.0 <= hi}


def test_paired_figure_ticks_label_the_whole_ci_range(keep_experiment_figures, tmp_path, recwarn):
    """Every panel carries plain-number ticks from below its lowest CI bound to above its highest (the demo's
    figure had a single tick "1" on one panel and none above 1 on the other, with CIs up to 1.6)."""
    from imunoise.experiments.plots import paired_figure

    entries = [_paired("plain", "gmwm", "rtk", 0.61, 0.88, 1.25), _paired("plain", "em", "rtk", 0.66, 1.03, 1.61),
               _paired("plain", "gmwm", "noise", 0.33, 0.55, 0.91),
               _paired("static_var", "gmwm", "rtk", 0.97, 1.02, 1.06),
               _paired("static_var", "em", "noise", 0.99, 1.30, 1.71),
               _paired("static_var", "gmwm", "noise", 0.94, 0.99, 1.05)]
    paired_figure(entries, tmp_path / "paired.png")
    fig = keep_experiment_figures[0]
    fig.canvas.draw()
    panels = [ax for ax in fig.axes if ax.get_xscale() == "log"]
    assert len(panels) == 2
    for ax, base in zip(panels, ("plain", "static_var"), strict=True):
        cis = [e["ci"] for e in entries if e["baseline"] == base]
        lo, hi = min(c[0] for c in cis), max(c[1] for c in cis)
        x0, x1 = ax.get_xlim()
        ticks = [v for v in ax.get_xticks() if x0 <= v <= x1]
        labels = [t.get_text() for t in ax.get_xticklabels() if x0 <= t.get_position()[0] <= x1]
        assert len(ticks) >= 3 and 1.0 in ticks, (base, ticks)
        assert ticks[0] <= lo and ticks[-1] >= hi, (base, ticks, lo, hi)  # labelled ticks enclose every CI
        assert sum(v > 1.0 for v in ticks) >= 1 and sum(v < 1.0 for v in ticks) >= 1
        assert labels == [f"{v:g}" for v in ticks], labels
        assert x0 <= lo and x1 >= hi
    assert not [w for w in recwarn.list if "matplotlib" in w.filename or "Legend" in str(w.message)]


def test_ratio_ticks_enclose_the_range_with_few_plain_numbers():
    from imunoise.experiments.plots import ratio_ticks

    assert ratio_ticks(0.33, 1.61) == [0.3, 0.5, 0.7, 1.0, 1.5, 2.0]
    assert ratio_ticks(0.94, 1.06) == [0.94, 0.96, 0.98, 1.0, 1.02, 1.04, 1.06]
    assert ratio_ticks(1.0, 1.0) == [0.98, 1.0, 1.02]  # a CI of zero width still gets a scale
    for lo, hi in ((0.59, 1.26), (0.2, 0.9), (1.1, 4.0), (0.02, 50.0), (0.999, 1.0005)):
        t = ratio_ticks(lo, hi)
        assert t[0] <= min(lo, 1.0) and t[-1] >= max(hi, 1.0) and 1.0 in t and len(t) <= 11, (lo, hi, t)


def _scenario_and_runs(with_outage_runs: bool):
    from types import SimpleNamespace

    t0 = 1000.0
    windows = [(1100.0, 60.0), (1300.0, 60.0)]
    t = np.arange(t0, t0 + 500.0, 1.0)
    sc = SimpleNamespace(init=SimpleNamespace(t=t0), windows=windows)
    full = SimpleNamespace(t=t, ecef=0.01 * np.ones((t.size, 3)), horizontal=0.02 * np.ones(t.size))
    obj = {"_err": full}
    if with_outage_runs:
        obj["_runs"] = [(w, None, SimpleNamespace(t=t, horizontal=1.0 + np.maximum(t - w[0], 0.0))) for w in windows]
    return sc, {"plain": obj, "gmwm": dict(obj)}


def test_error_figure_shades_outages_only_on_the_outage_panel(keep_experiment_figures, tmp_path, recwarn):
    from imunoise.experiments.plots import error_figure

    sc, objects = _scenario_and_runs(with_outage_runs=True)
    error_figure(sc, objects, tmp_path / "errors.png", ["plain", "gmwm"])
    axs = keep_experiment_figures[0].axes
    outage, full_gnss = axs[0], axs[1:4]
    assert len(outage.patches) == len(sc.windows)
    spans = sorted((p.get_x(), p.get_x() + p.get_width()) for p in outage.patches)
    assert spans == [(100.0, 160.0), (300.0, 360.0)]
    assert [len(ax.patches) for ax in full_gnss] == [0, 0, 0]  # GNSS was there throughout those runs
    assert outage.get_legend() is not None
    assert not recwarn.list, [str(w.message) for w in recwarn.list]


def test_figures_without_labelled_curves_warn_nothing(keep_experiment_figures, tmp_path):
    """A run with no outage runs (or no model updates) has nothing to put in a legend: no legend is asked
    for, so matplotlib's "No artists with labels found to put in legend" does not reach stderr."""
    import warnings
    from types import SimpleNamespace

    from imunoise.experiments.plots import error_figure, timeline_figure

    sc, objects = _scenario_and_runs(with_outage_runs=False)
    empty = SimpleNamespace(segments=[], gate_open=np.zeros(0, bool), sample_t=np.zeros(0), updates=[])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        error_figure(sc, objects, tmp_path / "errors.png", ["plain", "gmwm"])
        timeline_figure(empty, tmp_path / "timeline.png", 1000.0)
    assert keep_experiment_figures[0].axes[0].get_legend() is None


def test_timeline_compute_time_labels_do_not_overlap_in_the_saved_figure(keep_experiment_figures, tmp_path):
    """Labels measured on the final layout (legend outside included) and as many rows as they need: the
    saved figure has no two labels over each other, each under its own point and inside the axes."""
    from types import SimpleNamespace

    from imunoise.experiments.plots import timeline_figure

    t0 = 243263.0
    stops = [(t0 + 5, t0 + 30), (t0 + 200, t0 + 212), (t0 + 215, t0 + 221), (t0 + 224, t0 + 231)]
    updates = [SimpleNamespace(kind="identify", t_stop=t0 + 30, t_effect=t0 + 30.5, elapsed_s=[0.9] * 6)]
    updates += [SimpleNamespace(kind="refit", t_stop=t0 + 33 + 2 * k, t_effect=t0 + 33.2 + 2 * k,
                                elapsed_s=[0.0123] * 6) for k in range(7)]  # seven refits within 14 s
    updates += [SimpleNamespace(kind="refit", t_stop=t1, t_effect=t1 + 0.1, elapsed_s=[0.05] * 6) for _, t1 in stops]
    full = SimpleNamespace(segments=[SimpleNamespace(t0=a, t1=b) for a, b in stops],
                           gate_open=np.zeros(0, bool), sample_t=np.zeros(0), updates=updates)
    timeline_figure(full, tmp_path / "timeline.png", t0)
    fig = keep_experiment_figures[0]
    ax = fig.axes[0]
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    labels = [t for t in ax.texts if t.get_text()]  # the arrows are empty annotations
    boxes = [t.get_window_extent(r) for t in labels]
    assert len(boxes) == len(updates)
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), (labels[i].get_text(), labels[j].get_text())
    frame = ax.get_window_extent(r)
    assert all(frame.y0 <= b.y0 and b.y1 <= frame.y1 for b in boxes)  # none clipped below the axes
    assert sorted(t.get_position()[0] for t in labels) == pytest.approx(sorted(u.t_effect - t0 for u in updates))
