"""What a run is (``RunConfig``) and its file ``config.yaml``, checked when read.

``config.yaml`` is read like a scenario (``mjxskill.scenario.fields``: bounded, safe YAML, every
error names the file, the key and the line) and its settings go through the checks the flags
go through (``mjxskill.runs.settings``), so a hand-edited or damaged file is one
``RunError`` naming what is wrong instead of a run that loops forever or a traceback later.
Unknown keys are refused by name; a setting added after a run was written takes its default.
The run's parameter prior (``prior``: where it came from and ``mjxskill.gp.Prior``'s fields,
``mjxskill.training.priors``) is checked against the run's bounds when read, so a resumed run
uses the prior it started with.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Iterator

import yaml

from mjxskill import gp
from mjxskill.errors import RunError, quote
from mjxskill.gp.settings import DEFAULTS_BY_GENERATION, GENERATION, acquisition_defaults, acquisition_settings
from mjxskill.scenario.fields import Field, compose_text
from mjxskill.runs.evaluations_csv import FORCE_COLUMNS, POOLING_COLUMNS, SPREAD_PREFIX
from mjxskill.runs.settings import NO_DEFAULT, SETTINGS, cross_problems, optimizer_option_value
from mjxskill.runs.training_protocol import training_rows

FORMAT = "mjxskill.run/1"
CLUSTERS = ("ray",)  # what a run's ``cluster`` may say besides null
IDENTITY = ("task", "scenario", "parameter_names", "parameter_units", "bounds", "objective_names")


@dataclass(frozen=True)
class RunConfig:
    """What a run is: the task, its parameter space and objectives, and the training flags.

    task: scenario name ("push"); scenario: what ``load_scenario`` was given (a name or a path).
    bounds: ((lower...), (upper...)) in parameter order. optimizer_options: acquisition settings of
    the GP optimizer (``mjxskill.gp.AcquisitionSettings`` fields) other than its defaults
    (``--optimizer-option``). repeats > 1: this directory holds one
    sub-run per seed (``seed-<s>/``) and no evaluations of its own. The fields from ``goal`` on
    are the settings of ``mjxskill.runs.settings.SETTINGS``.
    """

    task: str
    scenario: str
    goal: str
    parameter_names: tuple[str, ...]
    parameter_units: tuple[str, ...]
    bounds: tuple[tuple[float, ...], tuple[float, ...]]
    objective_names: tuple[str, ...]
    budget: int
    batch_size: int
    n_init: int
    worlds: int
    seed: int
    episode_seconds: float
    repeats: int = 1
    optimizer_options: dict = field(default_factory=dict)  # {acquisition setting: value}, see optimizer_config
    engine: str = "mjx"  # the physics engine its batches run on (mjxskill.engine.build); "mjx" before the setting
    # "random": uniform random search after the warm-up; "optuna-*": one of Optuna's samplers; ...
    # (mjxskill.training.optimizers)
    optimizer: str = "mobo"
    # How the run spends its episodes (mjxskill.runs.training_protocol); "paper" before the setting.
    protocol: str = "paper"
    # The optimizer's parameter prior: {"source": text, "mean": (K, P), "std": (K, P), "weights":
    # (K,)} (mjxskill.training.priors); None: none (every run before priors).
    prior: dict | None = None
    # The generation of gp's acquisition defaults the run began with (gp.settings
    # DEFAULTS_BY_GENERATION): the options it does not name keep those defaults when it resumes.
    # Absent from config.yaml: 1, every run before the hypervolume defaults (issue 19).
    optimizer_defaults: int = field(default_factory=lambda: _optimizer_generations()[1])
    # "ray": the run was made to run its native episodes on a Ray cluster (--ray-address; the
    # address is not kept: it names a machine, not the run); None: on this machine. The results
    # do not depend on it, so a resume may run elsewhere.
    cluster: str | None = None
    # A resume with a scenario whose content differed from the run's copy, accepted by the user
    # (mjxskill.runs.run_task.record_scenario_change): ({"scenario": what it was resumed with,
    # "evaluations": rows before it, "difference": the first one, "previous_copy": file}, ...).
    scenario_changes: tuple = ()
    # Why the run uses ``engine``, as ``mjxskill.engine.build.resolve_engine`` said when this
    # configuration was made ("as asked", "auto: ..."): what a command's header prints. Not stored
    # (config.yaml, report.json): "" for a configuration read from its run, whose engine is its own.
    engine_reason: str = field(default="", compare=False)

    def to_yaml(self) -> str:
        data = {"format": FORMAT, **asdict(self)}
        del data["engine_reason"]
        data["parameter_names"] = list(self.parameter_names)
        data["parameter_units"] = list(self.parameter_units)
        data["bounds"] = [list(self.bounds[0]), list(self.bounds[1])]
        data["objective_names"] = list(self.objective_names)
        data["optimizer_options"] = dict(self.optimizer_options)
        data["prior"] = None if self.prior is None else {key: self.prior[key] for key in PRIOR_KEYS}
        data["scenario_changes"] = [dict(change) for change in self.scenario_changes]
        if not self.scenario_changes:  # config.yaml of a run never resumed so stays as it was
            del data["scenario_changes"]
        return yaml.safe_dump(data, sort_keys=False)

    @classmethod
    def from_yaml(cls, text: str, where: str) -> "RunConfig":
        """The configuration in ``text`` (the file ``where``); RunError names key and line."""
        root = compose_text(text, where, RunError)
        entries = dict(root.items()) if root.node.tag.endswith(":map") else {}
        if "format" not in entries or entries["format"].is_null() or entries["format"].scalar() != FORMAT:
            raise RunError(f"{where} is not an mjxskill run configuration (format {FORMAT!r} expected)")
        f = root.mapping(
            required=("format", *IDENTITY, *(s.name for s in SETTINGS if s.default is NO_DEFAULT)),
            optional=(*(s.name for s in SETTINGS if s.default is not NO_DEFAULT), "optimizer_options", "prior",
                      "optimizer_defaults", "cluster", "scenario_changes"),
        )
        names = _names(f["parameter_names"], "parameter")
        units = _texts(f["parameter_units"])
        if len(units) != len(names):
            f["parameter_units"].fail(f"expected {len(names)} units, one per parameter, got {len(units)}")
        bounds = f["bounds"].matrix(len(names))
        if len(bounds) != 2:
            f["bounds"].fail(f"expected two rows (lower, upper bounds), got {len(bounds)}")
        for i, (lower, upper) in enumerate(zip(*bounds)):
            if not lower < upper:
                f["bounds"].fail(f"{names[i]}: lower bound {lower:g} is not below the upper bound {upper:g}")
        values = {}
        for setting in SETTINGS:
            if setting.name not in f:
                values[setting.name] = setting.default
                continue
            try:
                values[setting.name] = setting.coerce(f[setting.name].scalar())
            except ValueError as err:
                f[setting.name].fail(str(err))
        for name, reason in cross_problems(values):
            f.get(name, root).fail(f"{name} {values[name]} {reason}")
        options = {}
        if "optimizer_options" in f and not f["optimizer_options"].is_null():
            for key, item in f["optimizer_options"].items():
                try:  # gp's acquisition settings, typed by gp (every key an older run wrote is one)
                    options[key] = optimizer_option_value(key, item.scalar())
                except ValueError as err:
                    item.fail(str(err))
        prior = None
        if "prior" in f and not f["prior"].is_null():
            prior = _prior(f["prior"], names, bounds)
        generation = 1
        if "optimizer_defaults" in f:
            generation = f["optimizer_defaults"].scalar()
            known = _optimizer_generations()[0]
            if isinstance(generation, bool) or generation not in known:
                f["optimizer_defaults"].fail(f"expected a generation of the optimizer's defaults "
                                             f"({', '.join(map(str, known))}), got {quote(generation)}")
        cluster = None
        if "cluster" in f and not f["cluster"].is_null():
            cluster = f["cluster"].scalar()
            if cluster not in CLUSTERS:
                f["cluster"].fail(f"expected one of {', '.join(CLUSTERS)} or null, got {quote(cluster)}")
        changes = _scenario_changes(f["scenario_changes"]) if "scenario_changes" in f else ()
        config = cls(task=f["task"].string(), scenario=f["scenario"].string(), parameter_names=names,
                     parameter_units=units, bounds=(tuple(bounds[0]), tuple(bounds[1])),
                     objective_names=_names(f["objective_names"], "objective"), optimizer_options=options, prior=prior,
                     optimizer_defaults=generation, cluster=cluster, scenario_changes=changes, **values)
        problem = optimizer_problem(config)
        if problem:
            f.get("optimizer_options", root).fail(problem)
        return config

    def columns(self) -> list[str]:
        """Header of evaluations.csv and pareto.csv."""
        return evaluation_columns(self.parameter_names, self.objective_names, self.pooled)

    @property
    def training_rows(self) -> int:
        """The evaluations the run trains with (``training_protocol.training_rows``): its budget,
        or under the robust protocol the share of it that leaves the rest to the race."""
        return training_rows(self.budget, self.protocol)

    @property
    def pooled(self) -> bool:
        """Whether the run pools a parameter set's worlds when it rolls it out again (the robust
        protocol, mjxskill.runs.training_protocol), so that its rows carry the pooling columns."""
        return self.protocol == "robust"

    def sub_run(self, seed: int) -> "RunConfig":
        """The configuration of repeat ``seed`` of a repeated run."""
        return replace(self, seed=seed, repeats=1)


PRIOR_KEYS = ("source", "mean", "std", "weights")
CHANGE_KEYS = ("scenario", "evaluations", "difference", "previous_copy")


def _scenario_changes(field: Field) -> tuple:
    """config.yaml's ``scenario_changes``: a list of mappings of CHANGE_KEYS."""
    changes = []
    for item in field.seq():
        f = item.mapping(required=("scenario", "difference"), optional=("evaluations", "previous_copy"))
        change: dict[str, str | int] = {"scenario": f["scenario"].string(), "difference": f["difference"].string()}
        if "evaluations" in f:
            change["evaluations"] = f["evaluations"].integer(minimum=0)
        if "previous_copy" in f:
            change["previous_copy"] = f["previous_copy"].string()
        changes.append(change)
    return tuple(changes)


def _prior(field: Field, names, bounds) -> dict:
    """config.yaml's ``prior``, checked as gp checks a Prior against the run's bounds."""
    f = field.mapping(required=PRIOR_KEYS)
    prior = {"source": f["source"].string(), "mean": [list(r) for r in f["mean"].matrix(len(names))],
             "std": [list(r) for r in f["std"].matrix(len(names))], "weights": list(f["weights"].vector())}
    try:
        gp_prior(prior).check_bounds(bounds)
    except ValueError as err:
        field.fail(f"{err} (parameters: {', '.join(names)})")
    return prior


def gp_prior(prior: dict | None):
    """The ``mjxskill.gp.Prior`` of a run's stored prior (None: none); ValueError if it is none."""
    if prior is None:
        return None
    return gp.Prior(mean=prior["mean"], std=prior["std"], weights=prior["weights"])


def _texts(field: Field) -> tuple[str, ...]:
    values = []
    for item in field.seq():
        value = item.scalar()
        if not isinstance(value, str):
            item.fail(f"expected a text, got {quote(value)}")
        values.append(value)
    return tuple(values)


def _names(field: Field, what: str) -> tuple[str, ...]:
    names = field.strings()
    if not names:
        field.fail(f"expected at least one {what} name")
    if len(set(names)) != len(names):
        field.fail(f"{what} names repeat: {list(names)}")
    return names


def _optimizer_generations():
    """(the known generations of gp's acquisition defaults, the current one)."""
    return tuple(DEFAULTS_BY_GENERATION), GENERATION


def optimizer_config(config: RunConfig):
    """The ``mjxskill.gp.MOBOConfig`` of a run: its parameter space, batches and seed, and the
    acquisition settings its optimizer options name (gp's defaults for the others). Builds gp's
    ``MOBOConfig``, which imports jax (``mjxskill.gp`` loads its names lazily): every command
    imports this module (through runs.run_dir), and its --help must not pay for that."""
    return gp.MOBOConfig(
        bounds=config.bounds,
        n_objectives=len(config.objective_names),
        batch_size=config.batch_size,
        n_init=config.n_init,
        seed=config.seed,
        acquisition=acquisition_settings(config.optimizer_options, acquisition_defaults(config.optimizer_defaults)),
        prior=gp_prior(config.prior),
    )


def optimizer_problem(config: RunConfig) -> str | None:
    """Why the optimizer refuses ``config`` (None: it accepts it). With the run's own fields
    checked before, what is left to refuse is an optimizer option, alone or with another (gp
    names it, e.g. n_restarts beyond n_raw)."""
    try:
        optimizer_config(config)
    except (ValueError, TypeError) as err:
        return str(err)
    return None


def evaluation_columns(parameter_names, objective_names, pooled: bool = False) -> list[str]:
    """The CSV header; ``pooled``: with the pooling columns of the robust protocol."""
    pooling = [*POOLING_COLUMNS, *(f"{SPREAD_PREFIX}{o}" for o in objective_names)] if pooled else []
    return ["iteration", *parameter_names, *(f"objective_{o}" for o in objective_names), "success_rate", *FORCE_COLUMNS,
            *pooling]


def batch_sizes(budget: int, batch_size: int, n_init: int) -> Iterator[int]:
    """Sizes of the successive batches of a run, as ``mjxskill.gp.ask`` proposes them: the
    warm-up stops at exactly ``n_init`` points and the last batch is cut to the budget."""
    n = 0
    while n < budget:
        q = min(batch_size, budget - n)
        if n < n_init:
            q = min(q, n_init - n)
        yield q
        n += q


__all__ = ["FORMAT", "PRIOR_KEYS", "RunConfig", "batch_sizes", "evaluation_columns", "gp_prior", "optimizer_config",
           "optimizer_problem"]
