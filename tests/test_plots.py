"""The figures (#23.15): the threshold episode marked, integer episode ticks, an env-steps
x axis, and one overlay figure per sweep. The figure is inspected before it is saved."""

from __future__ import annotations

import pytest
from matplotlib.ticker import MaxNLocator

from keras_rl.report import plots


def rows(n: int, steps: int = 200) -> list[dict]:
    return [
        {"episode": e, "steps": steps, "total_steps": e * steps, "score": -1000.0 + 10 * e, "metric": -1000.0 + 8 * e}
        for e in range(1, n + 1)
    ]


@pytest.fixture
def drawn(monkeypatch):
    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figures.append(fig))
    return figures


def test_the_threshold_episode_is_marked_and_ticks_are_whole_episodes(drawn, tmp_path):
    plots.plot_curve(tmp_path / "c.png", rows(60), -600, "t", "EMA", reached_at=51)
    ax = drawn[0].axes[0]
    marks = [line for line in ax.get_lines() if line.get_label().startswith("threshold reached")]
    assert len(marks) == 1 and list(marks[0].get_xdata()) == [51, 51]
    assert marks[0].get_label() == "threshold reached (episode 51)"
    assert isinstance(ax.xaxis.get_major_locator(), MaxNLocator) and ax.get_xlabel() == "episode"


def test_an_env_steps_axis_puts_each_episode_at_its_total_steps(drawn, tmp_path):
    plots.plot_curve(tmp_path / "c.png", rows(10), -600, "t", "EMA", reached_at=4, x_axis="steps")
    ax = drawn[0].axes[0]
    assert ax.get_xlabel() == "env steps"
    assert list(ax.get_lines()[0].get_xdata()) == [200 * e for e in range(1, 11)]
    assert any(line.get_label() == "threshold reached (episode 4, step 800)" for line in ax.get_lines())
    with pytest.raises(ValueError, match="x_axis must be one of"):
        plots.plot_curve(tmp_path / "c.png", rows(3), -600, "t", "EMA", x_axis="time")


def test_no_mark_when_the_threshold_was_not_reached(drawn, tmp_path):
    plots.plot_curve(tmp_path / "c.png", rows(10), -600, "t", "EMA", reached_at=None)
    assert not any(line.get_label().startswith("threshold reached") for line in drawn[0].axes[0].get_lines())


def test_the_sweep_figure_overlays_each_points_median_with_its_iqr(drawn, tmp_path):
    short, long = rows(5), rows(8)
    plots.plot_sweep(tmp_path / "s.png", {"a": [short, long, long], "b": [long]}, -600, "EMA", "sweep")
    ax = drawn[0].axes[0]
    medians = {line.get_label(): list(line.get_ydata()) for line in ax.get_lines()}
    assert medians["a (median of 3 seeds)"] == [r["metric"] for r in long]  # every seed has the same metric here
    assert len(ax.collections) == 2  # one IQR band per point


def test_a_curve_that_cannot_be_drawn_is_a_warning_not_an_error(tmp_path, monkeypatch, capsys):
    """The runs are on disk by then: a plot that fails (here matplotlib refusing the data)
    must not turn a finished command into a crash (issue #22)."""
    import keras_rl.report.plots as plots
    from keras_rl.dispatch.jobs import SeedJob
    from keras_rl.posts.pendulum import PendulumDDPGConfig

    def refuse(*args, **kwargs):
        raise ValueError("Axis limits cannot be NaN or Inf")

    monkeypatch.setattr(plots, "plot_seed_curve", refuse)
    job = SeedJob.of(PendulumDDPGConfig.for_variant("faithful", seed=4), tmp_path / "seed_4", command="x")
    plots.draw_job_curves(job)
    err = capsys.readouterr().err
    assert "warning: could not draw" in err and "ValueError: Axis limits" in err and "seed_4" in err


def test_quantiles_per_episode_leave_out_what_no_seed_played():
    import numpy as np

    runs = [rows(4), rows(2)]
    episodes, (q50,) = plots.metric_quantiles(runs, (50,))
    assert list(episodes) == [1, 2, 3, 4]
    assert q50[0] == -992.0 and q50[3] == -968.0  # episode 4: only the longer run
    cut, (q,) = plots.metric_quantiles(runs, (50,), episodes=2)
    assert list(cut) == [1, 2] and np.allclose(q, [-992.0, -984.0])
    assert len(plots.metric_quantiles([], (50,))[0]) == 0


def test_a_sweep_with_no_data_says_so_instead_of_an_empty_frame(drawn, tmp_path):
    plots.plot_sweep(tmp_path / "sweep.png", {"tau=0.001": [], "tau=0.01": []}, -300, "EMA", "t")
    texts = [t.get_text() for t in drawn[0].axes[0].texts]
    assert texts == ["no grid point has an episode yet"]


def test_the_check_figure_draws_the_baseline_as_a_band_and_each_fresh_seed(monkeypatch, tmp_path):
    from keras_rl.check import command
    from keras_rl.check.rules import rule_for
    from keras_rl.check.statistics import Decision
    from keras_rl.registry import get_experiment

    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figures.append(fig))
    baseline = {s: rows(60) for s in range(100)}
    new = {s: rows(50) for s in range(100, 110)}
    result = command.CheckResult(
        "pendulum",
        rule_for("pendulum", "smoke"),
        {s: 50.0 for s in baseline},
        {s: 50.0 for s in new},
        Decision(0.5, False, "Mann-Whitney U (two-sided)", 1.0),
        [],
        None,
    )
    command._plot(tmp_path / "check.png", get_experiment("pendulum"), result, baseline, new)
    curves = figures[0].axes[0]
    drawn_lines = [line for line in curves.get_lines() if len(line.get_xdata())]
    assert len(drawn_lines) <= len(new) + 3  # the fresh seeds, both medians, the threshold
    assert len(curves.collections) >= 2  # the baseline's bands


def test_the_check_figure_says_how_far_it_reads_ends_its_axis_there_and_labels_its_medians(monkeypatch, tmp_path):
    """Issue 54 item 4: the title said "first 1000 episodes" under an axis that ended at 250, the
    baseline median fell where a few slow seeds still played, and the median bars had no label."""
    from keras_rl.check import command
    from keras_rl.check.rules import rule_for
    from keras_rl.check.statistics import Decision
    from keras_rl.registry import get_experiment

    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figures.append(fig))
    baseline = {s: rows(60 if s < 60 else 250) for s in range(100)}  # 40 slow seeds play to 250
    new = {s: rows(50) for s in range(100, 110)}
    rule = rule_for("pendulum", "sensitive")
    result = command.CheckResult(
        "pendulum", rule, {s: 50.0 for s in baseline}, {s: 50.0 for s in new}, Decision(0.5, False, "U", 1.0), [], None
    )
    command._plot(tmp_path / "check.png", get_experiment("pendulum"), result, baseline, new)
    curves, dist = figures[0].axes
    assert f"reads up to episode {rule.episodes}" in curves.get_title()
    assert "the longest seed played 250" in curves.get_title()
    assert curves.get_xlim()[1] == 251
    median = next(line for line in curves.get_lines() if line.get_label().startswith("baseline median"))
    assert max(median.get_xdata()) == 60  # not the 40 slow seeds alone
    assert "median" in [t.get_text() for t in dist.get_legend().get_texts()]
    new_median = next(line for line in curves.get_lines() if line.get_label().startswith("new median"))
    assert max(new_median.get_xdata()) == 50 and new_median.get_zorder() > 1  # on top of the seeds' lines


def test_a_sets_curves_show_seeds_thin_a_median_band_and_where_each_met_the_threshold_without_a_seed_legend():
    """Round three: a 30-entry legend covered a third of the plot and ten colours repeated. Seeds
    are thin lines of one colour, the median and interquartile band stop where fewer than half the
    seeds still play (the few slow ones left are not the set), and each seed's first meeting of
    the threshold is marked."""
    from keras_rl.report.aggregate import draw_set_curves

    def rows(n, start):
        return [{"episode": e, "metric": float(start + e)} for e in range(1, n + 1)]

    curves = {0: rows(10, 0), 1: rows(10, 1), 2: rows(10, 2), 3: rows(50, 3)}
    fig = draw_set_curves(curves, {0: 5, 1: None, 2: 7, 3: None}, 8.0, "metric", "t")
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(labels) == 5 and labels[0] == "each of 4 seeds" and not any(t.startswith("seed ") for t in labels)
    median = next(line for line in ax.get_lines() if line.get_label().startswith("median"))
    assert list(median.get_xdata()) == list(range(1, 11))  # after episode 10 one seed of four plays
    marks = ax.collections[-1].get_offsets()
    assert [tuple(m) for m in marks] == [(5.0, 5.0), (7.0, 9.0)]


def test_the_checks_baseline_band_ends_where_fewer_than_half_its_seeds_still_play():
    """check.png's baseline median fell to -750 after episode 150, drawn from the few slow seeds
    still running: with ``min_share=0.5`` those episodes are left out."""
    from keras_rl.report.plots import metric_quantiles

    runs = [[{"metric": float(e)} for e in range(n)] for n in (10, 10, 12, 40)]
    x, _ = metric_quantiles(runs, (50,))
    assert x[-1] == 40
    x, (median,) = metric_quantiles(runs, (50,), min_share=0.5)
    assert list(x) == list(range(1, 13)) and median[-1] == 11.0
