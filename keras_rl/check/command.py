"""``keras-rl check``: fresh seeds against the committed baseline, by the post's rule.

For each experiment: its rule for the tier (``rules.py``), the fresh seeds run (in batches
where the post has a seed-batched learner), each seed's statistic for them and for the
baseline's runs (cut to the rule's episodes), the test, and the rule's measured error
rates (``keras_rl/check/calibration.json``, written by ``maintainers/calibrate/rules.py``).
Writes ``check.md``, ``check.json`` and per experiment ``<experiment>/check.png`` under
``--out``; the fresh runs go in ``<out>/<experiment>/seed_<n>``.

One command is one family of tests: with k posts, Holm's step-down adjustment keeps the chance
that any of them is called changed when none changed at most alpha (the rules' 0.01), not k
times it. A one-post command is its own rule, unadjusted. The report gives the family-wise
false-alarm rate of the command as it ran: each post's exact (untied statistics) or resampled
rate at Holm's first level alpha / k against its whole baseline, combined over the posts.

``--sequential`` runs the group-sequential design instead (``sequential.py``): fresh seeds in
looks of 5 up to 30 per post, each post stopping as changed or consistent at its own look,
with the efficacy level calibrated per post on its baseline to 1% / 3
(``keras_rl/check/sequential.json``, written by ``maintainers/calibrate/designs.py``), so the
family-wise rate of a command of up to three posts is at most 1% without Holm.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from keras_rl.atomic import atomic_write_json, atomic_write_text
from keras_rl.check.rules import CheckRule, rule_for
from keras_rl.check.sequential import SequentialDesign, at_level, run_design
from keras_rl.check.statistics import (
    Decision,
    command_false_alarm_rate,
    decide,
    decide_paired,
    family_false_alarm_rate,
    holm_adjusted,
    seed_statistic,
    settles_at_threshold,
)
from keras_rl.dispatch.options import RunOptions
from keras_rl.errors import ConfigError, NoVerdictError, RunFolderError, argument
from keras_rl.registry import get_experiment
from keras_rl.runs.files import read_episodes
from keras_rl.runs.run_set import RunSet
from keras_rl.runs.summary import RunSummary

CALIBRATION = Path(__file__).with_name("calibration.json")
"""The measured error rates of every rule: package data, so an installed ``keras_rl`` has them."""
SENSITIVE_RATES = Path(__file__).with_name("sensitive.json")
"""The sensitive tier's measured false-alarm rates and power (package data)."""
TWIN_RATES = Path(__file__).with_name("twins.json")
"""The twin rules' size and error rates on real changes (package data; ``python -m maintainers calibrate twins``)."""
TORCH_RATES = Path(__file__).with_name("torch.json")
"""``check --framework torch``'s rules measured on committed real runs (``python -m maintainers calibrate torch``)."""
SEQUENTIAL = Path(__file__).with_name("sequential.json")
"""Each post's calibrated sequential design and its measured rates (package data)."""
RATE_FILES = (CALIBRATION, SENSITIVE_RATES, TWIN_RATES, TORCH_RATES, SEQUENTIAL)
"""Every file of measured rates the reports quote, all package data."""
BASELINES = Path(__file__).resolve().parents[2] / "results" / "checks"
"""The committed baselines (``<experiment>/<rule.baseline>/runs.parquet``), in a checkout."""
PACKAGED_BASELINES = Path(__file__).with_name("baselines")
"""The same baselines as package data (``<experiment>/baseline/runs.parquet``, copies of the
checkout's, which a test holds equal), so an installed package checks without a checkout."""


def check_request(names: list[str], tier: str, framework: str = "keras") -> None:
    """The posts, tier and framework a check names, checked before TensorFlow loads: a typo is named
    in a second, not after the imports (a ConfigError); PyTorch's absence is named with its extra."""
    from keras_rl.check.rules import FRAMEWORKS, RULES, TIERS, rule_for

    known = sorted({e for e, _ in RULES}, key=["pendulum", "cartpole", "mountaincar"].index)
    unknown = [n for n in names if n not in known]
    if not names:
        raise ConfigError(f"no experiment named; check knows {', '.join(known)}")
    if unknown:
        raise ConfigError(f"unknown experiment {unknown[0]!r}; check knows {', '.join(known)}")
    if tier not in TIERS:
        raise ConfigError(f"unknown tier {tier!r}; choose one of {', '.join(TIERS)}")
    if len(set(names)) != len(names):
        raise ConfigError(f"an experiment is named twice: {' '.join(names)}")
    if framework not in FRAMEWORKS:
        raise ConfigError(f"unknown framework {framework!r}; choose one of {', '.join(FRAMEWORKS)}")
    if framework == "torch":
        for name in names:
            rule_for(name, tier, framework)
        from keras_rl.torch import check_torch

        check_torch()


def default_baselines() -> Path:
    """``--against``'s default: this checkout's committed baselines, else the package's own."""
    if BASELINES.is_dir():
        return BASELINES
    if PACKAGED_BASELINES.is_dir():
        return PACKAGED_BASELINES
    raise ConfigError(
        f"no committed baselines beside this keras_rl ({Path(__file__).resolve().parents[1]}) and none in "
        f"the package; pass {argument('against', 'FOLDER')}, a checkout's results/checks"
    )


MARKER = "check.json"


@dataclass(frozen=True)
class TwinReading:
    """What the twins' bits say: of the ``compared`` twins, ``identical`` reproduced their baseline
    seed row for row (every episode's score, metric and losses; wall time aside); ``parted`` gives
    each other twin's first differing episode."""

    compared: int
    identical: int
    parted: dict[int, int]
    to_threshold: bool = False
    """The reruns stopped at their threshold, so each was compared as far as it played."""

    @property
    def same_bits(self) -> bool:
        return self.compared > 0 and self.identical == self.compared

    def text(self) -> str:
        if self.same_bits:
            how = " (each to its threshold, or to its last episode)" if self.to_threshold else ""
            return f"the same bits as the baseline for {self.identical} of {self.compared} seeds{how}"
        where = ", ".join(f"seed {s} at episode {e}" for s, e in sorted(self.parted.items())[:3])
        more = "" if len(self.parted) <= 3 else f" and {len(self.parted) - 3} more"
        return (
            f"the same bits as the baseline for {self.identical} of {self.compared} seeds; the others part "
            f"({where}{more}), so the paired test decides"
        )


def first_difference(
    baseline_rows: list[dict[str, Any]], new_rows: list[dict[str, Any]], crossed_at: int | None = None
) -> int | None:
    """The first episode (from 1) where a rerun's row differs from its baseline seed's in anything but
    wall time, compared exactly (NaN equal to NaN); None when every row is the same bits.
    ``crossed_at``: the episode where the baseline seed first met its threshold, given where the
    rerun stops there (``seeds_stop_at_threshold``); a rerun that ended exactly there, while its
    baseline seed played on, is compared as far as it played. One that ended anywhere else (a
    non-finite loss, another budget) parts where it ended."""
    stopped = crossed_at is not None and len(new_rows) == crossed_at < len(baseline_rows)
    for i in range(len(new_rows) if stopped else max(len(baseline_rows), len(new_rows))):
        if i >= len(baseline_rows) or i >= len(new_rows):
            return i + 1
        a, b = baseline_rows[i], new_rows[i]
        for key in (set(a) | set(b)) - {k for k in (*a, *b) if k.startswith("wall")}:
            x, y = a.get(key), b.get(key)
            if x != y and not (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)):
                return i + 1
    return None


def _passes(experiment):
    """Whether a metric meets the post's faithful threshold."""
    config = experiment.config_cls.for_variant("faithful")
    metric = experiment.make_metric(config)
    return lambda m: metric.passes(m, config.threshold)


def first_crossing(experiment, rows: list[dict[str, Any]]) -> int | None:
    """The first episode (from 1) whose metric meets the post's faithful threshold; None if none does."""
    reached = seed_statistic("episodes_to_threshold", rows, len(rows), _passes(experiment)) if rows else None
    return None if reached is None or reached > len(rows) else int(reached)


def as_played(experiment, rows: dict[int, list], stops: bool) -> dict[int, list]:
    """Each seed's rows as a run that ``stops`` at its threshold would have played them."""
    if not stops:
        return rows
    return {s: r[: first_crossing(experiment, r) or len(r)] for s, r in rows.items()}


def read_twins(
    baseline_rows: dict[int, list],
    new_rows: dict[int, list],
    seeds: list[int],
    experiment=None,
    stops: bool = False,
) -> TwinReading:
    """What the twins' bits say; ``stops``: the reruns stop at ``experiment``'s threshold."""
    crossed = {s: first_crossing(experiment, baseline_rows[s]) if stops else None for s in seeds}
    parted = {s: e for s in seeds if (e := first_difference(baseline_rows[s], new_rows[s], crossed[s])) is not None}
    return TwinReading(len(seeds), len(seeds) - len(parted), parted, stops)


@dataclass
class CheckResult:
    experiment: str
    rule: CheckRule
    baseline: dict[int, float]
    """Seed -> the statistic, for the baseline's runs."""
    new: dict[int, float]
    decision: Decision
    overrides: list[str]
    error_rates: dict[str, Any] | None
    """The rule's measured false-alarm rate and power, if calibrated."""
    adjusted_p: float | None = None
    """Holm's adjusted p over the command's posts (``decision.changed`` follows it)."""
    looks: list[dict[str, Any]] | None = None
    """Sequential checks: each look's fresh seeds and p, in order (the last one decided)."""
    design: dict[str, Any] | None = None
    """Sequential checks: the calibrated design and its measured false-alarm rate."""
    config_changes: tuple[str, ...] = ()
    """Fields of the code's faithful config that differ from the baseline's recorded one
    (``field: was -> now``): a changed default, reported beside the verdict."""
    twins: TwinReading | None = None
    """Twin checks: how many twins gave their baseline seed's bits, and where the others parted;
    None for an unpaired check."""
    fallback: str | None = None
    """Why a twin rule ran unpaired (a baseline that does not hold its twin seeds)."""
    environment: dict[str, Any] | None = None
    """What differs between the baseline's machine and libraries and the fresh runs' (``environment_changes``)."""
    baseline_note: str | None = None
    """Why the rule's measured error rates do not apply (a baseline other than the committed one)."""

    @property
    def verdict(self) -> str:
        return "changed" if self.decision.changed else "consistent"


def baseline_values(
    experiment, rule: CheckRule, folder: Path
) -> tuple[dict[int, float], dict[int, list[dict[str, Any]]]]:
    """Each baseline seed's statistic (and its rows, for the plot); a clear error if the
    folder is not a finished faithful baseline."""
    runs = RunSet(folder).runs()
    if not runs:
        raise RunFolderError(
            f"no baseline at {folder} (expected seed_<n>/ folders or a runs.parquet); "
            f"{argument('against')} names the folder "
            "that holds <experiment>/baseline"
        )
    values, rows_of = {}, {}
    first = None
    for run in runs:
        summary = run.summary()
        if summary.experiment != experiment.name:
            raise RunFolderError(
                f"{run.where} is a baseline of {summary.experiment}, not of {experiment.name}: "
                f"{argument('against')} names the folder that holds {experiment.name}/baseline"
            )
        made = experiment.config_cls.from_dict(run.config())
        # The faithful variant as the code that made the baseline had it: a default changed since
        # is what the check exists to see, so it is reported (config_changes), never refused.
        if made.variant != "faithful":
            raise RunFolderError(
                f"{run.where} is a run of the {made.variant!r} variant; a baseline must be the faithful variant"
            )
        engine = summary.provenance.get("engine", "gymnasium")
        for field_name, theirs, ours in (
            ("framework", made.framework, rule.framework),
            ("matched_init", made.matched_init, False),
            ("engine", engine, rule.engine),
        ):
            if theirs != ours:
                raise RunFolderError(
                    f"{run.where} was made with {field_name} {theirs!r}; the {rule.tier} tier of {experiment.name} "
                    f"trains its fresh seeds with {field_name} {ours!r}, and a baseline must be made the same way"
                )
        first = made if first is None else first
        differing = made.differs_from(first)
        if differing:
            raise RunFolderError(
                f"{run.where} was made with another config than {runs[0].where} ({', '.join(differing[:3])} "
                "differ); a baseline's runs share one config but for the seed"
            )
        if summary.status != "completed":
            raise RunFolderError(f"{run.where} did not finish ({summary.status}); a baseline needs finished runs")
        rows = run.rows(expected_rows=summary.rows_expected)
        values[summary.seed], rows_of[summary.seed] = _statistic(experiment, rule, rows), rows
    return values, rows_of


def baseline_config(experiment, folder: Path):
    """The config the baseline's runs share (its first seed's ``config.json``)."""
    return experiment.config_cls.from_dict(RunSet(folder).runs()[0].config())


def config_changes(experiment, folder: Path) -> list[str]:
    """``field: baseline's value -> the code's value`` for each field where the code's faithful
    config now differs from the one the baseline recorded (a changed default shows here,
    beside the verdict that says whether it changed the behaviour)."""
    made = baseline_config(experiment, folder)
    now = experiment.config_cls.for_variant("faithful", episodes=made.episodes, framework=made.framework)
    was, wanted = made.to_dict(), now.to_dict()
    return [f"{k}: {was.get(k)!r} -> {wanted.get(k)!r}" for k in made.differs_from(now)]


def check_baseline_size(name: str, statistic: str, n_baseline: int, n_new: int, alpha: float) -> None:
    """A ConfigError when no outcome of ``n_new`` fresh seeds could give p < alpha against a
    baseline of ``n_baseline`` seeds (the most extreme one, computed by the rule's own test),
    naming the smallest baseline that could."""
    from keras_rl.check.statistics import smallest_p

    if smallest_p(statistic, n_baseline, n_new) < alpha:
        return
    minimum = next((m for m in range(n_baseline + 1, 10_001) if smallest_p(statistic, m, n_new) < alpha), None)
    raise ConfigError(
        f"{name}: a baseline of {n_baseline} seed(s) cannot flag anything with {n_new} fresh seeds at "
        f"alpha {alpha:.3g} (the smallest p the test can give is {smallest_p(statistic, n_baseline, n_new):.3g}); "
        + (f"it needs at least {minimum} seeds" if minimum else "no baseline size is enough at this alpha")
    )


def twin_seeds(
    name: str, rule: CheckRule, wanted: list[int], baseline: dict[int, float], chosen: bool
) -> tuple[CheckRule, list[int], str | None]:
    """A twin rule's seeds: ``wanted`` where the baseline holds every one of them; else the rule
    unpaired, on fresh seeds, with the reason for the report (a baseline of the user's own that
    does not hold the twins). Seeds the user chose (``chosen``) must be all the baseline's or none."""
    held = [s for s in wanted if s in baseline]
    if len(held) == len(wanted):
        return rule, wanted, None
    if chosen and held:
        raise ConfigError(
            f"{name}: seeds {held[:5]} are the baseline's and {[s for s in wanted if s not in baseline][:5]} are not; "
            "a twin check reruns the baseline's seeds, an unpaired one runs seeds the baseline does not hold: "
            "give one kind or the other"
        )
    unpaired = rule.unpaired()
    fresh = wanted if chosen else unpaired.seed_list()
    reason = (
        f"the baseline holds seeds {min(baseline)}-{max(baseline)} ({len(baseline)}), not the twins "
        f"{rule.first_seed}-{rule.first_seed + rule.seeds - 1} this rule reruns"
        if not chosen
        else "the seeds given are not the baseline's"
    )
    return unpaired, fresh, f"unpaired against fresh seeds: {reason}"


def committed_baseline(folder: Path, rule: CheckRule) -> bool:
    """Whether ``folder`` is the committed baseline the rule's error rates were measured on, byte for
    byte (a checkout's or the package's copy)."""
    mine, theirs = folder / "runs.parquet", PACKAGED_BASELINES / rule.experiment / rule.baseline / "runs.parquet"
    return mine.is_file() and theirs.is_file() and mine.read_bytes() == theirs.read_bytes()


def measured_for(folder: Path, result: CheckResult) -> dict[str, Any]:
    """``CheckResult`` fields for a baseline other than the committed one: its error rates were never
    measured on it, so none is claimed; the note says what can be said (issue 72 item 6)."""
    if result.twins is not None and result.twins.same_bits or committed_baseline(folder, result.rule):
        return {}
    from keras_rl.check.statistics import smallest_p

    n = len(result.new)
    if result.twins is not None:
        floor = 2.0 / 2**n
        how = f"the smallest p its paired test allows with {n} twins is {floor:.3g}"
    else:
        floor = smallest_p(result.rule.statistic, len(result.baseline), n)
        how = f"the smallest p its test allows with {n} fresh seeds against {len(result.baseline)} is {floor:.3g}"
    return {
        "error_rates": None,
        "baseline_note": (
            f"this baseline ({folder}, {len(result.baseline)} seeds) is not the committed one the rule's error rates "
            "were measured on, so its false alarms on real changes and its power are not measured (a false-alarm "
            f"figure in the table is its test's size on this baseline, its seeds taken as exchangeable); {how}"
        ),
    }


def check_twin_count(name: str, statistic: str, n: int, alpha: float) -> None:
    """A ConfigError when n twins could never give p < alpha: the paired test's smallest p
    (every twin moved one way) is ``2 / 2**n``."""
    if 2.0 / 2**n < alpha:
        return
    need = next(k for k in range(1, 64) if 2.0 / 2**k < alpha)
    raise ConfigError(
        f"{name}: {n} twin(s) cannot flag anything at alpha {alpha:.3g} (the paired test's smallest p is "
        f"{2.0 / 2**n:.3g}); it needs at least {need}"
    )


def _statistic(experiment, rule: CheckRule, rows: list[dict[str, Any]]) -> float:
    return seed_statistic(rule.statistic, rows, rule.episodes, _passes(experiment), experiment.success_at_end)


def rates_source(rule: CheckRule) -> str:
    """The package-data file a rule's error rates come from."""
    if rule.framework == "torch":
        return TORCH_RATES.name
    return (TWIN_RATES if rule.twins else SENSITIVE_RATES if rule.tier == "sensitive" else CALIBRATION).name


def seeds_stop_at_threshold(rule: CheckRule) -> bool:
    """Nothing after the threshold moves the rule's statistic, so its solo seeds stop there (post
    003's sensitive twins played 23% of their wall time after it). A seed batch keeps every seed to
    the end, so that its arithmetic, shared by the batch, stays whole."""
    return rule.seed_batch == 1 and settles_at_threshold(rule.statistic, get_experiment(rule.experiment).success_at_end)


def describe_plan(
    rule: CheckRule,
    fresh: list[int],
    baseline: int,
    design,
    fallback: str | None = None,
    committed: bool = True,
    stopping: bool | None = None,
) -> str:
    """One post's plan, as ``check --dry-run`` prints it. ``committed``: the baseline is the committed
    one the rule's error rates were measured on (else none is quoted, issue 72 item 6). ``stopping``:
    the seeds stop at their threshold (``seeds_stop_at_threshold`` unless a ``--set`` says otherwise)."""
    stopping = seeds_stop_at_threshold(rule) if stopping is None else stopping
    rates = error_rates(rule) if committed else None
    if not committed:
        measured = "error rates not measured for this baseline (they were measured on the committed one)"
    elif rates and (rule.twins or "real_power" in rates):
        measured = power_text(rates, source=rates_source(rule))
    elif rates:
        power = power_text(rates, source=rates_source(rule))
        measured = f"measured false-alarm rate {rates['false_alarm_rate']:.3g}, power {power}"
    else:
        measured = "error rates not calibrated for this rule"
    if design is not None:  # the fixed rule's measured rates are not the design's
        measured = f"false alarms at most {design[1]:.3g} by its design (sequential.json)"
    how = f"sequential, looks up to {design[0].stages[-1]} seeds" if design else f"alpha {rule.alpha}"
    engine = "" if rule.engine == "gymnasium" else f" on the {rule.engine} engine"
    seeds = (
        f"twin seeds {fresh[0]}-{fresh[-1]} ({len(fresh)}; the first {rule.bits_seeds} run first, "
        "and the same bits stop it there)"
        if rule.twins
        else f"fresh seeds {fresh[0]}-{fresh[-1]} ({len(fresh)})"
    )
    stops = ", each seed stopping at its threshold if it gets there" if stopping else ""
    return (
        f"{rule.experiment} ({rule.tier}): {rule.statistic} over {rule.episodes} episodes{stops}, {how}; "
        f"{seeds}{engine} against a baseline of {baseline}; {measured}" + (f" [{fallback}]" if fallback else "")
    )


def what_it_sees(rule: CheckRule) -> str:
    """What a tier can see, for the line beside a "consistent" verdict: its measured power, and,
    where a finer tier exists for the post, that a smaller change needs it (a 20% change of one
    learning rate read "consistent, p = 0.154" at the smoke tier, with nothing saying why)."""
    from keras_rl.check.rules import RULES

    rates = error_rates(rule)
    source = rates_source(rule)
    if rule.twins:
        seen = power_text(rates, source=source) if rates else "error rates not measured (twins.json)"
    else:
        seen = f"power {power_text(rates, source=source)}" if rates else "power not calibrated"
    if rule.framework == "torch":  # measured on real changes only, and no finer tier yet
        return f"the PyTorch {rule.tier} tier: {seen}"
    text = f"the {rule.tier} tier sees gross breakage ({seen})" if rule.tier != "sensitive" else f"{seen}"
    finer = RULES.get((rule.experiment, "sensitive"))
    if finer is not None and rule.tier != "sensitive":
        fine = error_rates(finer)
        how = f"; {power_text(fine, source=rates_source(finer))}" if fine else ""
        text += (
            f"; a smaller change, such as 10-20% of one hyperparameter, is the sensitive tier's (--tier sensitive{how})"
        )
    return text


def power_text(rates: dict[str, Any], short: bool = False, source: str = "calibration.json") -> str:
    """A rule's measured power in words: against the tuning mutants (gross / all), or for the
    sensitive tier against a 10% move of the median and the held-out mutants; ``source``: the
    file it was read from, named in the long form."""
    if "rule" in rates and ("power" in rates or "not_measured" in rates):  # twins.json
        if "not_measured" in rates:
            return "not measured" if short else f"error rates not measured: {rates['not_measured']}"
        big = {n: r for n, r in rates["power"].items() if abs(math.log(r["true_shift"])) >= math.log(1.1) - 1e-12}
        seen = ", ".join(f"{n} (x{r['true_shift']:.2f}) {r['resampled_holm_first']:.0%}" for n, r in big.items())
        if short:
            return f"{min(r['resampled_holm_first'] for r in big.values()):.0%} (least)" if big else "-"
        false = twin_false_alarm(rates, 3)
        alarms = f"; false alarms on real arithmetic changes {false:.1%} at 0.01 / 3" if false is not None else ""
        text = (
            f"twins at 0.01 / 3 against the held-out mutants that move the median 10% or more: {seen}{alarms}"
            if big
            else f"twins: no held-out mutant that moves the median 10% or more has landed{alarms}"
        )
        return f"{text} ({source})"
    if "real_power" in rates:  # torch.json: real changes only
        power = rates["real_power"]
        if short:
            return f"{min(r['resampled'] for r in power.values()):.0%} (least)"
        seen = ", ".join(f"{n} (x{r['true_shift']:.2f}) {r['resampled']:.0%}" for n, r in power.items())
        return (
            f"against real changes of the algorithm: {seen}; false alarms on real arithmetic changes "
            f"{rates['false_alarm_rate']:.1%} ({source})"
        )
    if "shift_power" in rates:
        moved = rates["shift_power"]
        text = f"{moved['x0.90']:.0%} / {moved['x1.10']:.0%} against a median 10% lower / higher"
    elif "power_gross" in rates:
        if short:
            return f"{rates['power_gross']:.0%} / {rates['power_all']:.0%}"
        text = f"{rates['power_all']:.0%} over the mutants"
    else:
        text = f"{rates['held_out_power']:.0%} over the held-out mutants"
    return text if short else f"{text} ({source})"


def error_rates(rule: CheckRule, calibration: Path = CALIBRATION) -> dict[str, Any] | None:
    """The calibrated error rates of exactly this rule, or None if it was never measured
    (the sensitive tier's are in ``SENSITIVE_RATES``, by ``python -m maintainers calibrate sensitive``)."""
    if rule.twins:
        return twin_rates(rule)
    if rule.framework == "torch":
        return torch_rates(rule)
    if rule.tier == "sensitive":
        return sensitive_rates(rule)
    if not calibration.is_file():
        return None
    entry = json.loads(calibration.read_text()).get(rule.experiment, {}).get("tiers", {}).get(rule.tier)
    if not entry or "candidates" not in entry:
        return None
    measured = next(
        (
            c
            for c in entry.get("candidates", [])
            if c["statistic"] == rule.statistic
            and c["alpha"] == rule.alpha
            and c["seeds"] == rule.seeds
            and c["episodes"] == rule.episodes
        ),
        None,
    )
    return measured


def torch_rates(rule: CheckRule, path: Path = TORCH_RATES) -> dict[str, Any] | None:
    """A PyTorch rule's rates on real runs (``torch.json``), or None where the rule measured there is
    not this one."""
    if not path.is_file():
        return None
    entry = json.loads(path.read_text()).get(rule.experiment, {}).get(rule.tier)
    if not entry or entry["rule"] != rule_fields(rule):
        return None
    return entry


def rule_fields(rule: CheckRule) -> dict[str, Any]:
    """What makes a rule the one its rates were measured for."""
    return {k: getattr(rule, k) for k in ("statistic", "alpha", "seeds", "episodes", "engine", "framework")}


def twin_rates(rule: CheckRule, path: Path = TWIN_RATES) -> dict[str, Any] | None:
    """A twin rule's size and rates on real changes (``twins.json``), or None where the rule
    measured there is not this one."""
    if not path.is_file():
        return None
    entry = json.loads(path.read_text())["posts"].get(rule.experiment)
    if not entry or (entry["rule"]["seeds"], entry["rule"]["statistic"]) != (rule.seeds, rule.statistic):
        return None
    return entry


def twin_false_alarm(rates: dict[str, Any] | None, posts: int) -> float | None:
    """A twin rule's highest measured false-alarm rate over the real arithmetic changes, at Holm's
    first level for a three-post command, else at alpha (an upper bound for two posts); None where
    none was measured."""
    key = "resampled_holm_first" if posts == 3 else "resampled_alpha"
    measured = [r[key] for r in (rates or {}).get("false_alarms", {}).values() if r[key] == r[key]]
    return max(measured) if measured else None


def sensitive_rates(rule: CheckRule, path: Path = SENSITIVE_RATES) -> dict[str, Any] | None:
    """The sensitive tier's measured rates of exactly this rule, or None."""
    from keras_rl.check.rules import UNPAIRED_SENSITIVE

    if not path.is_file() or UNPAIRED_SENSITIVE.get(rule.experiment) != rule:
        return None
    entry = json.loads(path.read_text()).get("posts", {}).get(rule.experiment)
    if not entry:
        return None
    rule_of = entry["rule"]
    if (rule_of["statistic"], rule_of["seeds"], rule_of["episodes"], rule_of["alpha"]) != (
        rule.statistic,
        rule.seeds,
        rule.episodes,
        rule.alpha,
    ):
        return None
    return entry["rates"]


def sequential_design(rule: CheckRule, path: Path = SEQUENTIAL) -> tuple[SequentialDesign, float]:
    """The post's calibrated design for this tier and its false-alarm rate under no change,
    as ``maintainers/calibrate/designs.py --write`` committed them; a ConfigError if absent."""
    entries = json.loads(path.read_text())["results"] if path.is_file() else []
    entry = next(
        (e for e in entries if (e["post"], e["tier"], e["statistic"]) == (rule.experiment, rule.tier, rule.statistic)),
        None,
    )
    if entry is None:
        raise ConfigError(
            f"{rule.experiment} has no calibrated sequential design for the {rule.tier} tier in {path}; "
            f"run python -m maintainers calibrate designs --write, or check without {argument('sequential')}"
        )
    design = entry["design"]
    null = next(row for row in entry["rows"] if row["scenario"] == "no change")
    return (
        SequentialDesign(tuple(design["stages"]), design["efficacy"], design["futility"]),
        float(null["sequential_changed"]),
    )


def prepare_out(out: Path) -> None:
    """``--out`` holds nothing, or an earlier check's output (replaced): never anything else."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{argument('out', out)} is a file; check needs a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file():
        raise ConfigError(
            f"{argument('out', out)} holds files that are not a check's output; refusing to touch them: "
            "pass an empty or new folder"
        )


def run_check(
    names: list[str],
    tier: str,
    against: Path,
    out: Path,
    seeds: list[int] | None,
    options: RunOptions,
    sequential: bool = False,
    sequential_alpha: float | None = None,
    dry_run: bool = False,
    framework: str = "keras",
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
) -> list[CheckResult]:
    """Run the fresh seeds of every experiment at once, then test each against its baseline
    (fixed-n, Holm over the posts); or, ``sequential``, look after every stage of seeds and
    stop each post where its design decides. ``sequential_alpha``: the command's false-alarm
    bound instead of the committed designs' 1%, split over the posts and each post's looks
    (``sequential.at_level``; a bisect step's share of its alpha). ``dry_run``: every input
    checked and each post's plan printed, nothing trained or written. ``overrides``: each post's typed
    config changes (post -> field -> value; ``config.replace``), none by default."""
    prepare_out(out)  # a folder of someone else's files is named before anything else
    plan = []
    designs: dict[str, tuple[SequentialDesign, float]] = {}
    fallbacks: dict[str, str | None] = {}
    for name in names:
        experiment = get_experiment(name)
        rule = rule_for(name, tier, framework)
        if sequential:
            designs[name] = sequential_design(rule)
            if sequential_alpha is not None:
                share = sequential_alpha / len(names)
                designs[name] = (at_level(designs[name][0], share), share)
            fresh = list(range(rule.first_seed, rule.first_seed + designs[name][0].stages[-1]))
        else:
            fresh = seeds if seeds is not None else rule.seed_list()
        baseline, baseline_rows = baseline_values(experiment, rule, Path(against) / name / rule.baseline)
        if rule.twins:
            rule, fresh, fallbacks[name] = twin_seeds(name, rule, fresh, baseline, seeds is not None)
        clash = [] if rule.twins else sorted(set(fresh) & set(baseline))
        if clash:
            raise ConfigError(
                f"{name}: seeds {clash} are the baseline's own; check runs fresh seeds "
                f"(the baseline has {min(baseline)}-{max(baseline)})"
            )
        if len(fresh) < 2:
            raise ConfigError(f"{name}: a check needs at least 2 fresh seeds, got {len(fresh)}")
        level = designs[name][0].efficacy if sequential else rule.alpha
        if rule.twins:
            check_twin_count(name, rule.statistic, len(fresh), level)
        else:
            check_baseline_size(name, rule.statistic, len(baseline), len(fresh), level)
        config = experiment.config_cls.for_variant("faithful", episodes=rule.episodes, framework=rule.framework)
        if seeds_stop_at_threshold(rule):
            config = config.replace(stop_at_threshold=True)
        config = config.replace(**(overrides or {}).get(name, {}))
        plan.append((experiment, rule, fresh, config, baseline, baseline_rows))
    if dry_run:
        for experiment, rule, fresh, config, baseline, _rows in plan:
            committed = committed_baseline(Path(against) / experiment.name / rule.baseline, rule)
            planned = designs.get(experiment.name)
            fallback = fallbacks.get(experiment.name)
            print(describe_plan(rule, fresh, len(baseline), planned, fallback, committed, config.stop_at_threshold))
        return []
    for experiment, *_ in plan:
        if (out / experiment.name).exists():
            shutil.rmtree(out / experiment.name)
    atomic_write_json(out / MARKER, {"status": "running", "experiments": names})
    results: list[CheckResult] = []
    plots: list[tuple] = []
    if not sequential:
        # twins: their first bits_seeds run first (beside every unpaired post's seeds); a post whose
        # twins all give their baseline seed's bits stops there, the others run the rest
        first = {
            experiment.name: fresh[: rule.bits_seeds] if rule.twins else fresh for experiment, rule, fresh, *_ in plan
        }
        _run_seeds(
            out,
            [(experiment, rule, config, first[experiment.name]) for experiment, rule, _f, config, *_ in plan],
            options,
        )
        readings: dict[str, TwinReading] = {}
        for experiment, rule, _fresh, config, _baseline, baseline_rows in plan:
            if rule.twins:
                _new, rows = _read_new(out / experiment.name, experiment, rule, first[experiment.name])
                readings[experiment.name] = read_twins(
                    baseline_rows, rows, first[experiment.name], experiment, config.stop_at_threshold
                )
        rest = [
            (experiment, rule, config, fresh[rule.bits_seeds :])
            for experiment, rule, fresh, config, *_ in plan
            if rule.twins and not readings[experiment.name].same_bits
        ]
        if rest:
            _run_seeds(out, rest, options)
        for experiment, rule, fresh, config, baseline, baseline_rows in plan:
            reading = readings.get(experiment.name)
            if reading is not None and reading.same_bits:
                ran = first[experiment.name]
                new, new_rows = _read_new(out / experiment.name, experiment, rule, ran)
                decision = Decision(1.0, False, "the same bits as the baseline", float(len(ran)))
                baseline_of = {s: baseline[s] for s in ran}
            elif reading is not None:
                new, new_rows = _read_new(out / experiment.name, experiment, rule, fresh)
                reading = read_twins(baseline_rows, new_rows, fresh, experiment, config.stop_at_threshold)
                baseline_of = {s: baseline[s] for s in fresh}
                decision = decide_paired(
                    [baseline[s] for s in fresh], [new[s] for s in fresh], rule.statistic, rule.alpha
                )
            else:
                new, new_rows = _read_new(out / experiment.name, experiment, rule, fresh)
                baseline_of = baseline
                decision = decide(list(baseline.values()), list(new.values()), rule.statistic, rule.alpha)
            result = CheckResult(
                experiment.name,
                rule,
                baseline_of,
                new,
                decision,
                override_texts(overrides, experiment.name),
                error_rates(rule),
                twins=reading,
                fallback=fallbacks.get(experiment.name),
            )
            results.append(result)
            # the baseline as far as a run that stops where the fresh ones do would have played
            played = as_played(experiment, baseline_rows, config.stop_at_threshold)
            plots.append((out / experiment.name / "check.png", experiment, result, played, new_rows))
        adjust_for_family(results)
    else:
        active = list(plan)
        done: dict[str, tuple[CheckResult, tuple]] = {}
        looks: dict[str, list[dict[str, Any]]] = {experiment.name: [] for experiment, *_ in plan}
        stages = designs[plan[0][0].name][0].stages
        for k, n in enumerate(stages):
            previous = stages[k - 1] if k else 0
            _run_seeds(
                out,
                [(experiment, rule, config, fresh[previous:n]) for experiment, rule, fresh, config, *_ in active],
                options,
            )
            still = []
            for entry in active:
                experiment, rule, fresh, config, baseline, baseline_rows = entry
                design, null_rate = designs[experiment.name]
                new, new_rows = _read_new(out / experiment.name, experiment, rule, fresh[:n])
                decision = decide(list(baseline.values()), list(new.values()), rule.statistic, design.efficacy)
                looks[experiment.name].append({"seeds": n, "p": decision.p})
                outcome = run_design(design, [look["p"] for look in looks[experiment.name]])
                if outcome.verdict == "continue":
                    still.append(entry)
                    continue
                decision = replace(decision, changed=outcome.verdict == "changed")
                result = CheckResult(
                    experiment.name,
                    rule,
                    baseline,
                    new,
                    decision,
                    override_texts(overrides, experiment.name),
                    error_rates(rule),
                    looks=looks[experiment.name],
                    design={
                        **asdict(design),
                        "false_alarm_rate": null_rate,
                        "level": "committed" if sequential_alpha is None else "union bound",
                    },
                )
                done[experiment.name] = (
                    result,
                    (
                        out / experiment.name / "check.png",
                        experiment,
                        result,
                        as_played(experiment, baseline_rows, config.stop_at_threshold),
                        new_rows,
                    ),
                )
            active = still
            if not active:
                break
        for experiment, *_ in plan:
            result, plot = done[experiment.name]
            results.append(result)
            plots.append(plot)
    changes = {
        experiment.name: tuple(config_changes(experiment, Path(against) / experiment.name / rule.baseline))
        for experiment, rule, *_ in plan
    }
    results = [
        replace(
            r,
            config_changes=changes[r.experiment],
            environment=fresh_environment(Path(against) / r.experiment / r.rule.baseline, out / r.experiment, r),
            **measured_for(Path(against) / r.experiment / r.rule.baseline, r),
        )
        for r in results
    ]
    for args in plots:
        _plot(*args)
    write_report(out, results, tier)
    return results


def _run_seeds(out: Path, groups: list[tuple], options: RunOptions) -> None:
    """Train each (experiment, rule, config, seeds) group's seeds into ``out/<experiment>/``, on
    the rule's engine, in the rule's seed batches, all groups' jobs at once."""
    from keras_rl.dispatch.backends import train_seeds
    from keras_rl.dispatch.jobs import SeedJob, batched
    from keras_rl.learners.table import batch_refusal
    from keras_rl.report.plots import draw_job_curves

    jobs = []
    for experiment, rule, config, fresh in groups:
        group = [
            SeedJob.of(
                config.replace(seed=s), out / experiment.name / f"seed_{s}", start="overwrite", engine=rule.engine
            )
            for s in fresh
        ]
        # a --set no stacked learner covers (post 001's learning phase) runs its seeds alone
        size = rule.seed_batch if batch_refusal(experiment.name, config) is None else 1
        jobs += batched(group, size)
    outcome = train_seeds(jobs, options, after_job=draw_job_curves, pack=False)
    if outcome.interrupted:
        raise KeyboardInterrupt


def override_texts(overrides: Mapping[str, Mapping[str, Any]] | None, experiment: str) -> list[str]:
    """A post's config changes as ``check.json`` and ``check.md`` record them: ``FIELD=VALUE``,
    each value as a folder name writes it, sorted by field."""
    from keras_rl.config import value_text

    return [f"{k}={value_text(v)}" for k, v in sorted((overrides or {}).get(experiment, {}).items())]


def _read_new(folder: Path, experiment, rule: CheckRule, fresh: list[int]) -> tuple[dict, dict]:
    """Each fresh seed's statistic and rows; NoVerdictError for a seed that did not finish."""
    new, new_rows = {}, {}
    for s in fresh:
        try:
            summary = RunSummary.read(folder / f"seed_{s}")
        except RunFolderError as exc:
            raise NoVerdictError(f"{experiment.name} seed {s} left no readable summary: {exc}") from None
        episodes = folder / f"seed_{s}" / "episodes.csv"
        rows = read_episodes(episodes) if episodes.is_file() else []
        if summary.status not in ("completed", "non_finite_loss") or not rows:
            raise NoVerdictError(f"{experiment.name} seed {s} did not finish ({summary.status}: {summary.message})")
        new[s] = _statistic(experiment, rule, rows) if summary.status == "completed" else float("nan")
        new_rows[s] = rows
    return new, new_rows


def family_alpha(results: list[CheckResult]) -> float:
    alphas = {r.rule.alpha for r in results}
    if len(alphas) != 1:
        raise ConfigError(f"the posts of one check have different alphas {sorted(alphas)}; one family needs one")
    return alphas.pop()


def adjust_for_family(results: list[CheckResult]) -> None:
    """Holm over the command's posts: each verdict from its adjusted p against the family's alpha."""
    if not results:
        return
    alpha = family_alpha(results)
    for result, adjusted in zip(results, holm_adjusted([r.decision.p for r in results])):
        result.adjusted_p = adjusted
        result.decision = replace(result.decision, changed=adjusted < alpha)


def command_false_alarm(results: list[CheckResult]) -> dict[str, Any]:
    """The whole command's false-alarm rate as it ran: each post's rate at Holm's first level
    (alpha / k: under no change, some post fires only if the smallest p clears it) for its
    number of fresh seeds against its whole baseline, combined as independent tests."""
    alpha = family_alpha(results)
    level = alpha / len(results)
    posts: dict[str, dict[str, Any]] = {}
    for r in results:
        if r.twins is not None and r.twins.same_bits:
            posts[r.experiment] = {"rate": 0.0, "method": "the same bits: no twin moved"}
        elif r.twins is not None:
            rate = twin_false_alarm(r.error_rates, len(results))
            how = "measured on real arithmetic changes (twins.json)" if rate is not None else "not measured"
            posts[r.experiment] = {"rate": rate, "method": how}
        else:
            posts[r.experiment] = asdict(
                command_false_alarm_rate(list(r.baseline.values()), len(r.new), r.rule.statistic, level)
            )
    rates = [p["rate"] for p in posts.values()]
    family = None if None in rates else family_false_alarm_rate(rates)
    return {"alpha": alpha, "posts": len(results), "level_per_post": level, "per_post": posts, "family_wise": family}


def sequential_false_alarm(results: list[CheckResult]) -> dict[str, Any]:
    """A sequential command's false-alarm rate: each post's calibrated design's measured rate
    under no change (``keras_rl/check/sequential.json``), combined as independent tests."""
    rates = {r.experiment: float(r.design["false_alarm_rate"]) for r in results if r.design is not None}
    return {"posts": len(rates), "per_post": rates, "family_wise": family_false_alarm_rate(list(rates.values()))}


def write_report(out: Path, results: list[CheckResult], tier: str, command: str | None = None) -> None:
    from keras_rl.runs.provenance import command_line

    command = command or command_line()
    lines = [
        f"# keras-rl check, tier {tier}",
        "",
        f"Command: `{command}`",
        "",
        "| experiment | statistic | test | baseline median (n) | new median (n) | p | p (Holm) | alpha | verdict "
        "| false alarms (as tested) | power (gross / all mutants) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    sequential = bool(results) and all(r.design is not None for r in results)
    family = (sequential_false_alarm if sequential else command_false_alarm)(results) if results else None
    for r in results:
        rates = r.error_rates
        pw = power_text(rates, short=True) if rates else "not calibrated"
        if r.design is not None:  # the fixed rule's rates are not this design's
            fa, pw = f"{r.design['false_alarm_rate']:.2%} (sequential)", "sequential.json"
        else:  # the figure the sentence below combines: this post at the level it was tested at
            assert family is not None
            rate = family["per_post"][r.experiment]["rate"]
            fa = "not measured" if rate is None else f"{rate:.2%} at {family['level_per_post']:.3g}"
        alpha = r.rule.alpha if r.design is None else f"{r.design['efficacy']:.3g} (sequential)"
        lines.append(
            f"| {r.experiment} | {r.rule.statistic} (first {r.rule.episodes} episodes) | "
            f"{r.decision.test} | {_median(r.baseline)} ({len(r.baseline)}) | {_median(r.new)} "
            f"({len(r.new)}) | {r.decision.p:.3g} | {_adjusted(r)} | {alpha} | **{r.verdict}** | {fa} | {pw} |"
        )
    if sequential and family is not None:
        for r in results:
            assert r.looks is not None and r.design is not None
            seen = "; ".join(f"{look['seeds']} seeds: p = {look['p']:.3g}" for look in r.looks)
            lines += [
                "",
                f"{r.experiment}, sequential (looks at {', '.join(map(str, r.design['stages']))} fresh seeds; changed "
                f"below p = {r.design['efficacy']:.3g}, consistent above {r.design['futility']} from the second look): "
                f"{seen}; stopped at {len(r.new)} seeds, **{r.verdict}**.",
            ]
        per_post = ", ".join(f"{name} {rate:.2%}" for name, rate in family["per_post"].items())
        if all(r.design.get("level") == "union bound" for r in results if r.design is not None):
            how = (
                "each post's share of the command's --alpha split over its looks, the union bound, with no "
                f"simulation: at most {per_post}"
            )
        else:
            how = (
                "each post's design calibrated on its own baseline to 1% / 3, futility stops included; "
                f"measured: {per_post}; sequential.json"
            )
        lines += [
            "",
            f"False alarms of this command as a whole: at most **{family['family_wise']:.2%}** when nothing "
            f"changed ({how}). No Holm step: the split is in the designs.",
        ]
    elif family is not None and family["family_wise"] is None:
        missing = [name for name, p in family["per_post"].items() if p["rate"] is None]
        lines += [
            "",
            f"False alarms of this command as a whole: **not measured**: {', '.join(missing)} ran twins whose bits "
            "differ from the baseline's, and their rate on real arithmetic changes is not measured yet "
            "(twins.json).",
        ]
    elif family is not None:
        methods = sorted({p["method"] for p in family["per_post"].values()})
        level = "alpha" if family["posts"] == 1 else f"alpha / {family['posts']}"
        above = family["family_wise"] > family["alpha"]
        lines += [
            "",
            f"False alarms of this command as a whole: **{family['family_wise']:.2%}** when nothing changed "
            f"(alpha {family['alpha']} for the family of {family['posts']} post(s), Holm: each post's figure in "
            f"the table, at {level} against its whole baseline, {'; '.join(methods)}, "
            "combined as independent tests)."
            + (
                " **Above alpha**: on this baseline the test is not exact at this level ("
                + (
                    "Fisher's test on few seeds"
                    if any(r.rule.statistic == "success" for r in results)
                    else "the rank test's normal approximation, with the ties of seeds that never reached the threshold"
                )
                + "); a larger baseline or more fresh seeds brings it down."
                if above
                else ""
            ),
        ]
        if all(r.error_rates for r in results):
            sources = ", ".join(sorted({rates_source(r.rule) for r in results}))
            against = (
                "real changes of the algorithm (the least shown)"
                if all(r.rule.framework == "torch" for r in results)
                else "the mutants"
            )
            lines.append(f"The power column is the rule's, measured against {against} ({sources}).")
    for r in results:
        if r.twins is not None:
            lines += ["", f"{r.experiment}: twins (the baseline's own seeds, rerun): {r.twins.text()}."]
        if r.fallback is not None:
            lines += ["", f"{r.experiment}: {r.fallback}."]
        if r.error_rates is None and r.rule.tier == "sensitive" or r.baseline_note:
            lines += ["", f"{r.experiment}: {r.baseline_note or 'error rates not measured for this rule'}."]
    lines += environment_lines(results)
    for r in results:
        if r.config_changes:
            lines += [
                "",
                f"{r.experiment}: the code's faithful config differs from the baseline's recorded one: "
                + "; ".join(f"`{c}`" for c in r.config_changes)
                + f". The verdict ({r.verdict}) says whether the behaviour changed with it.",
            ]
    if any(r.overrides for r in results):
        lines += ["", "New runs with: " + ", ".join(f"`--set {o}`" for o in results[0].overrides)]
    lines += [
        "",
        "Unpaired fresh seeds are never the baseline's; twins are its own seeds, rerun. "
        "`changed` means p < alpha in either direction "
        "(learning faster is a change in fidelity too). The error rates quoted here ship with the package "
        f"({', '.join(f'keras_rl/check/{f.name}' for f in RATE_FILES)}); "
        "how each was measured: docs/check.md in the project's repository.",
        "",
    ]
    atomic_write_text(out / "check.md", "\n".join(lines))
    payload = {
        "tier": tier,
        "command": command,
        "status": "finished",
        "changed": any(r.decision.changed for r in results),
        "false_alarm": family,
        "sequential": sequential,
        "experiments": [
            {
                "experiment": r.experiment,
                "rule": asdict(r.rule),
                "verdict": r.verdict,
                "decision": asdict(r.decision),
                "adjusted_p": r.adjusted_p,
                "overrides": r.overrides,
                "baseline": {str(k): v for k, v in r.baseline.items()},
                "new": {str(k): v for k, v in r.new.items()},
                "error_rates": r.error_rates,
                "looks": r.looks,
                "design": r.design,
                "config_changes": list(r.config_changes),
                "pairing": "twins" if r.twins is not None else "unpaired",
                "twins": None if r.twins is None else {**asdict(r.twins), "same_bits": r.twins.same_bits},
                "fallback": r.fallback,
                "baseline_note": r.baseline_note,
                "environment": r.environment,
            }
            for r in results
        ],
    }
    atomic_write_json(out / MARKER, payload)


LIBRARIES = ("tensorflow", "keras", "numpy", "gymnasium", "torch", "python", "keras_rl")
"""The versions a run records (``provenance.library_versions``) that a check compares."""
IMPORTS = ("tensorflow", "keras", "numpy", "gymnasium", "torch")
"""The libraries whose import another distribution may provide (``keras`` by ``keras-nightly``,
``tensorflow`` by ``tf-nightly``): each import is named as its library is."""


def providers(versions: dict[str, str]) -> dict[str, str]:
    """Library -> the installed distribution that provides its import, where that is another one
    than the library's own: of the distributions that install the import's files (``keras`` and
    ``keras-nightly`` both do, once TensorFlow 2.22.0rc0 pulls the second in beside the first), the
    one whose version is the version the import reports (``versions``, as a run records them)."""
    from importlib.metadata import packages_distributions, version

    found = packages_distributions()
    out = {}
    for library in IMPORTS:
        names = list(dict.fromkeys(found.get(library, [])))
        imported = versions.get(library)
        owner = next((n for n in names if imported is not None and _same_version(version(n), imported)), None)
        if owner is None and len(names) == 1:
            owner = names[0]
        if owner is not None and owner.lower().replace("_", "-") != library:
            out[library] = owner
    return out


def _same_version(a: str, b: str) -> bool:
    """``2.22.0rc0`` (a distribution's) and ``2.22.0-rc0`` (``tf.__version__``) are one version."""
    from packaging.version import InvalidVersion, Version

    try:
        return Version(a) == Version(b)
    except InvalidVersion:
        return a == b


def environment_changes(baseline_summary: dict[str, Any], new_summary: dict[str, Any]) -> dict[str, Any]:
    """What the fresh runs' machine and libraries change from the baseline's, as the two summaries
    recorded them: each library whose version differs (``was -> now``), each import now provided by
    another distribution than the one of its name (the baseline's recorded no provider: made with the
    project's pins, each was its own), and the CPU model and instruction set of both."""
    was, now = baseline_summary.get("versions", {}), new_summary.get("versions", {})
    versions = {
        k: {"was": was.get(k), "now": now.get(k)}
        for k in LIBRARIES
        if (k in was or k in now) and was.get(k) != now.get(k)
    }
    bp, np_ = baseline_summary.get("provenance", {}), new_summary.get("provenance", {})
    cpu = {
        "baseline": {"model": bp.get("cpu_model"), "isa": bp.get("cpu_isa")},
        "new": {"model": np_.get("cpu_model"), "isa": np_.get("cpu_isa")},
    }
    arithmetic = {"baseline": bp.get("environment", {}), "new": np_.get("environment", {})}
    return {
        "versions": versions,
        "replaced": providers(now),
        "cpu": cpu,
        "same_cpu": cpu["baseline"] == cpu["new"],
        "arithmetic": arithmetic if arithmetic["baseline"] != arithmetic["new"] else None,
    }


def _isa(isa: list[str] | None) -> str:
    """An instruction-set list, as its widest vector extension."""
    if not isa:
        return "instruction set not recorded"
    return "AVX-512" if "avx512f" in isa else "AVX2" if "avx2" in isa else isa[-1]


def fresh_environment(baseline: Path, fresh: Path, result: CheckResult) -> dict[str, Any] | None:
    """``environment_changes`` between the baseline's first seed and the first fresh seed's summary
    (None where no fresh seed left one)."""
    summary = fresh / f"seed_{min(result.new)}" / "summary.json"
    if not summary.is_file():
        return None
    return environment_changes(RunSet(baseline).runs()[0].summary_record(), json.loads(summary.read_text()))


def environment_lines(results: list[CheckResult]) -> list[str]:
    """The report's lines on what changed around the code: versions, replaced packages, the CPU."""
    lines: list[str] = []
    for r in results:
        env = r.environment
        if env is None:
            continue
        if env["versions"]:
            changed = "; ".join(f"`{k} {v['was']} -> {v['now']}`" for k, v in env["versions"].items())
        else:
            changed = "none: every library the baseline recorded has its version"
        replaced = "; ".join(f"`{k}` is provided by `{d}`" for k, d in env["replaced"].items())
        b, n = env["cpu"]["baseline"], env["cpu"]["new"]
        lines += [
            "",
            f"{r.experiment}: versions that differ from the baseline's: {changed}."
            + (
                f" Replaced: {replaced} (the baseline was made with `{'`, `'.join(env['replaced'])}` itself)."
                if replaced
                else ""
            )
            + f" CPU: {n['model']} ({_isa(n['isa'])}) against the baseline's {b['model']} ({_isa(b['isa'])})"
            + ("." if env["same_cpu"] else ": another CPU, and bits follow the host.")
            + (
                f" The arithmetic's environment differs: `{env['arithmetic']['new'] or 'none set'}` against the "
                f"baseline's `{env['arithmetic']['baseline'] or 'none set'}`."
                if env.get("arithmetic")
                else ""
            ),
        ]
    return lines


def _adjusted(result: CheckResult) -> str:
    return "-" if result.adjusted_p is None else f"{result.adjusted_p:.3g}"


def _median(values: dict[int, float]) -> str:
    finite = [v for v in values.values() if math.isfinite(v)]
    return f"{np.median(finite):.4g}" if finite else "n/a"


def _plot(path: Path, experiment, result: CheckResult, baseline_rows: dict, new_rows: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from keras_rl.report.plots import save_figure

    episodes = result.rule.episodes
    fig, (curves, dist) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [2, 1]})
    from keras_rl.report.plots import metric_quantiles

    # the baseline as a band (its 100 curves would hide the fresh seeds), the fresh seeds one by one
    # while at least half the baseline still plays: later, its few slow seeds are not the baseline
    x, (q05, q25, q50, q75, q95) = metric_quantiles(
        list(baseline_rows.values()), (5, 25, 50, 75, 95), episodes, min_share=0.5
    )
    # the fresh seeds thin and underneath, the two medians on top: 80 fresh lines hid the baseline
    for rows in new_rows.values():
        metric = [r["metric"] for r in rows[:episodes]]
        curves.plot(range(1, len(metric) + 1), metric, color="tab:orange", alpha=0.35, lw=0.6, zorder=1)
    curves.plot([], [], color="tab:orange", alpha=0.6, lw=0.8, label=f"new ({len(new_rows)} seeds, one line each)")
    curves.fill_between(x, q05, q95, color="tab:blue", alpha=0.15, lw=0, zorder=2, label="baseline 5-95%")
    curves.fill_between(x, q25, q75, color="tab:blue", alpha=0.35, lw=0, zorder=2, label="baseline IQR")
    curves.plot(
        x,
        q50,
        color="tab:blue",
        lw=1.8,
        zorder=3,
        label=f"baseline median ({len(baseline_rows)} seeds, while half play)",
    )
    nx, (new_median,) = metric_quantiles(list(new_rows.values()), (50,), episodes, min_share=0.5)
    curves.plot(nx, new_median, color="tab:red", lw=1.8, zorder=3, label="new median (while half play)")
    config = experiment.config_cls.for_variant("faithful")
    curves.axhline(config.threshold, color="k", ls="--", lw=0.8, label="threshold")
    curves.set_xlabel("episode")
    curves.set_ylabel(experiment.metric_label(config))
    played = max([len(rows[:episodes]) for rows in (*baseline_rows.values(), *new_rows.values())], default=0)
    curves.set_title(
        f"{result.experiment}: learning curves (the rule reads up to episode {episodes}; "
        f"the longest seed played {played})",
        fontsize=9,
    )
    curves.set_xlim(0, max(played, 1) + 1)
    curves.legend(fontsize=8)
    curves.grid(alpha=0.3)
    rng = np.random.default_rng(0)
    for i, values in enumerate((result.baseline, result.new)):
        v = np.asarray([x for x in values.values() if math.isfinite(x)])
        dist.scatter(i + rng.uniform(-0.08, 0.08, len(v)), v, alpha=0.7)
        if len(v):
            dist.hlines(np.median(v), i - 0.2, i + 0.2, color="k", label="median" if i == 0 else None)
    dist.set_xticks([0, 1], ["baseline", "new"])
    dist.set_ylabel(result.rule.statistic)
    dist.set_title(f"p = {result.decision.p:.3g}: {result.verdict}", fontsize=10)
    dist.grid(alpha=0.3, axis="y")
    if dist.get_legend_handles_labels()[0]:
        dist.legend(fontsize=8)
    save_figure(fig, path)
