"""The training settings of a run, one table for the command-line flags and ``config.yaml``.

A ``Setting`` is one ``RunConfig`` field: its ``config.yaml`` key, its flag, its type and
bounds, where its default comes from (the scenario's value, or a fixed one). ``train`` builds
its flags from ``SETTINGS`` and ``RunConfig.from_yaml`` reads the file with the very same
``Setting.coerce``, so a value the flags refuse is refused in a hand-edited ``config.yaml``
too (``batch_size: 0`` used to loop forever). A new setting is one row here and one field of
``RunConfig`` (``tests/runs/test_settings.py`` checks that the two agree).

``cross_problems`` holds the checks that involve several settings, and
``optimizer_option_value`` the check of one ``--optimizer-option`` / ``optimizer_options``
entry, both for either source. The optimizer options are not a table here: they are the
acquisition settings of ``mjxskill.gp`` (``AcquisitionSettings``), named, typed and checked by gp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from mjxskill.errors import QUOTE_CHARS, quote
from mjxskill.gp.settings import setting_value
from mjxskill.runs.bounds import call_episodes_problem
from mjxskill.scenario.schema import (MAX_BATCH, MAX_BUDGET, MAX_EPISODE_SECONDS, MAX_REPEATS,
                                     MAX_SEED, MAX_WORLDS, MIN_N_INIT)


from mjxskill.runs.training_protocol import PROTOCOLS, training_rows

NO_DEFAULT = object()
# Optuna's multi-objective samplers, an optional extra (mjxskill.training.optuna_search)
OPTUNA_OPTIMIZERS = ("optuna-nsga2", "optuna-tpe", "optuna-gp")
# BoTorch's qLogNEHVI, an optional extra (mjxskill.training.botorch_search)
BOTORCH_OPTIMIZERS = ("botorch-qlognehvi",)
OPTIMIZERS = ("mobo", "random", *OPTUNA_OPTIMIZERS, *BOTORCH_OPTIMIZERS)


@dataclass(frozen=True)
class Setting:
    """name: RunConfig field and config.yaml key. flag: the train option. kind: "int",
    "float" (positive and finite) or "text". scenario: the scenario's default (None: ``default``);
    default: the value of a run whose config.yaml predates the setting (NO_DEFAULT: required)."""

    name: str
    flag: str
    kind: str
    help: str
    minimum: float | None = None
    maximum: float | None = None
    unit: str = ""
    scenario: Callable[[Any], Any] | None = None
    default: Any = NO_DEFAULT
    choices: tuple[str, ...] | None = None
    default_text: str | None = None  # the flag's default for its help, when not the scenario's or ``default``

    def coerce(self, value):
        """The checked value of a flag's text or a config.yaml scalar; ValueError says why not."""
        if self.kind == "text":
            if not isinstance(value, str) or not value.strip():
                raise ValueError(f"expected a text, got {quote(value)}")
            if self.choices is not None and value not in self.choices:
                raise ValueError(f"expected one of {', '.join(self.choices)}, got {quote(value)}")
            return value
        number = _int(value) if self.kind == "int" else _float(value)
        show = (lambda v: _text(int(v))) if self.kind == "int" else (lambda v: f"{v:g}")  # noqa: E731
        unit = f" {self.unit}" if self.unit else ""
        if self.kind == "float" and not number > 0:
            raise ValueError(f"must be a positive finite number, got {_text(value)}")
        if self.minimum is not None and number < self.minimum:
            raise ValueError(f"must be at least {show(self.minimum)}{unit}, got {show(number)}")
        if self.maximum is not None and number > self.maximum:
            raise ValueError(f"must be at most {show(self.maximum)}{unit}, got {show(number)}")
        return number

    def default_for(self, scn):
        return self.scenario(scn) if self.scenario is not None else self.default


def _text(value) -> str:
    """A value as the user wrote it, cut to a short prefix (``mjxskill.errors.quote``)."""
    text = str(value)
    return text if len(text) <= QUOTE_CHARS else f"{text[:QUOTE_CHARS]}... ({len(text)} characters)"


def _int(value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, str)):
        raise ValueError(f"expected an integer, got {quote(value)}")
    try:
        return int(value)
    except ValueError:
        raise ValueError(f"expected an integer, got {quote(value)}") from None


def _float(value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f"expected a number, got {quote(value)}")
    try:
        number = float(value)
    except (ValueError, OverflowError):
        raise ValueError(f"expected a number, got {quote(value)}") from None
    if not math.isfinite(number):
        raise ValueError(f"must be a positive finite number, got {_text(value)}")
    return number


SETTINGS: tuple[Setting, ...] = (
    Setting("goal", "--goal", "text", "PDDL goal to plan instead of the scenario's", scenario=lambda scn: scn.goal),
    Setting("budget", "--budget", "int", "evaluations (parameter sets) per run; the robust protocol spends 1.15 x "
            "budget x worlds episodes: 3/4 of the budget in evaluations, the rest in its race", minimum=1,
            maximum=MAX_BUDGET,
            scenario=lambda scn: scn.optimizer.budget),
    Setting("batch_size", "--batch-size", "int", "parameter sets per batch", minimum=1, maximum=MAX_BATCH,
            scenario=lambda scn: scn.optimizer.batch_size),
    Setting("n_init", "--init", "int", "random warm-up evaluations", minimum=MIN_N_INIT,
            scenario=lambda scn: scn.optimizer.n_init),
    Setting("worlds", "--worlds", "int", "randomized worlds per parameter set", minimum=1, maximum=MAX_WORLDS,
            scenario=lambda scn: scn.randomization.n_worlds),
    Setting("seed", "--seed", "int", "seed of the optimizer and the worlds", minimum=0, maximum=MAX_SEED,
            scenario=lambda scn: scn.optimizer.seed),
    Setting("episode_seconds", "--episode-seconds", "float", "episode length in s", maximum=MAX_EPISODE_SECONDS,
            unit="s", scenario=lambda scn: scn.episode_seconds),
    Setting("repeats", "--repeats", "int", "independent runs with seeds seed..seed+N-1", minimum=1, maximum=MAX_REPEATS,
            default=1),
    # A new run stores the engine "auto" resolves to (mjxskill.engine.build); runs from before the
    # setting ran on MJX.
    Setting("engine", "--engine", "text", "physics engine: mjx (compiled MJX), native (native MuJoCo, one process "
            "per core) or auto (MJX on a GPU/TPU, native on a CPU)", scenario=lambda scn: "auto", default="mjx",
            choices=("mjx", "native", "auto"), default_text="auto"),
    # Random search, Optuna's samplers and BoTorch's qLogNEHVI are runs like any other, to
    # compare the optimizer with (mjxskill.experiment, benchmarks/task_optimizers.py): the same
    # batches, the same warm-up, then their proposals instead of the model's.
    Setting("optimizer", "--optimizer", "text", "what proposes the batches after the warm-up: mobo (the "
            "multi-objective Bayesian optimizer), random (uniform random search, a baseline) or one of Optuna's "
            "samplers to compare with: optuna-nsga2, optuna-tpe, optuna-gp (pip install 'mjxskill[optuna]'; "
            "optuna-gp: 'mjxskill[optuna-gp]') or BoTorch's botorch-qlognehvi (pip install 'mjxskill[botorch]')",
            default="mobo", choices=OPTIMIZERS),
    # How a run spends its episodes (mjxskill.runs.training_protocol): "robust" rolls promising
    # parameter sets out again in fresh worlds while it trains, makes the success rate's lower
    # bound an objective of its own and races the front for its pick; "paper" is the paper's
    # protocol (every evaluation in fresh worlds, its objectives), every run before the setting.
    Setting("protocol", "--protocol", "text", "how the run spends its episodes: robust (parameter sets that look "
            "best rolled out again in fresh worlds, the success rate's lower bound an objective, the front raced "
            "for the pick) or paper (the paper's protocol: each parameter set once, in its batch's worlds)",
            scenario=lambda scn: "robust", default="paper", choices=PROTOCOLS, default_text="robust"),
)
BY_NAME = {s.name: s for s in SETTINGS}
SEED = BY_NAME["seed"]  # evaluate's and select's --seed have the same bounds


def cross_problems(values: dict) -> list[tuple[str, str]]:
    """(setting name, problem) for checks over several settings, e.g. the warm-up within the
    budget; the caller puts where the value came from in front."""
    problems = []
    rows = training_rows(values["budget"], values.get("protocol", "paper"))
    if values["n_init"] > rows:
        problems.append(("n_init", f"exceeds the budget of {values['budget']} evaluations" if rows == values["budget"] else
                         f"exceeds the {rows} evaluations the robust protocol trains with of the budget of "
                         f"{values['budget']} (the race has the rest)"))
    episodes = call_episodes_problem(values["batch_size"] * values["worlds"], f"with batches of {values['batch_size']}")
    if episodes is not None:
        problems.append(("worlds", episodes))
    if values["seed"] + values.get("repeats", 1) - 1 > MAX_SEED:
        problems.append(("repeats", f"make seeds beyond {MAX_SEED} (seed {values['seed']})"))
    return problems


def optimizer_option_value(key: str, value):
    """The checked value of one ``--optimizer-option KEY=VALUE`` / ``optimizer_options`` entry
    (a number or a string, e.g. ``n_raw=256`` or ``model=scalarized``), as gp types it;
    ValueError names the key (listing the valid ones) or the value. The options are gp's
    ``AcquisitionSettings`` fields; the run's parameter space, batches and seed are no option.
    gp checks what several options must satisfy together when the run's ``MOBOConfig`` is
    built (``run_config.optimizer_problem``)."""
    return setting_value(key, value)


__all__ = ["BOTORCH_OPTIMIZERS", "BY_NAME", "NO_DEFAULT", "OPTIMIZERS", "OPTUNA_OPTIMIZERS", "SEED", "SETTINGS", "Setting", "cross_problems", "optimizer_option_value"]
