"""Argument types shared by the commands: a bad value becomes argparse's own "invalid value"
message with exit code 2."""

from __future__ import annotations

import argparse
import math
from typing import Any, Callable

from mjxskill.errors import QUOTE_CHARS, quote
from mjxskill.runs.bounds import MAX_PER_CONFIG, MAX_VALIDATION_CANDIDATES, workers_problem


def add_task_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("task", help="scenario name (push, peg) or path of a scenario YAML file")


MAX_FRAME_SIDE = 8192  # pixels of a rendered frame's side (8K); a frame is held whole in memory


def add_workers_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--workers", type=workers_count, metavar="N",
                        help="native engine: worker processes a call's episodes are split over (default: one per "
                             "core, the fastest measured; 1: this process). Results do not depend on it")


def workers_count(text: str) -> int:
    """``--workers`` of every command: at least 1, and no more worker processes than the
    machine's available memory holds (``mjxskill.runs.bounds.workers_problem``, the numbers in
    the message)."""
    value = positive_int(text)
    problem = workers_problem(value)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return value


workers_count.__name__ = "worker count"


def add_cluster_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--ray-address", dest="ray_address", metavar="auto|HOST:PORT",
                        help="native engine: run a call's episodes on the Ray cluster at this address, one actor per "
                             "CPU of the cluster (auto: the one `ray start` started here, or $RAY_ADDRESS; pip install "
                             "'mjxskill[ray]'). Results do not depend on it")


def describe_cluster(info, at_a_time: int = 1, actors: int | None = None) -> str:
    """The header line of a run on a cluster: ``ray: N nodes, C CPUs`` and what runs there
    (an experiment: ``at_a_time`` repetitions at the same time on ``actors`` actors each)."""
    if at_a_time > 1:
        return (f"{info.describe()} at {info.address}: {at_a_time} repetitions at a time, each on {actors} actor"
                f"{'s' * (actors != 1)} of the native engine (one per CPU in all), the optimizers and the files here")
    return (f"{info.describe()} at {info.address}: the native engine's episodes on {info.cpus} actor"
            f"{'s' * (info.cpus != 1)} (one per CPU), the optimizer and the run's files here")


def add_validation_arguments(parser: argparse.ArgumentParser, when: str, default: str) -> None:
    """The pick's validation flags (``mjxskill.evaluation.validation``) of experiment and evaluate;
    ``when``: to which picks they apply, ``default``: what applies without the flag (for the help)."""
    parser.add_argument("--validation-per-config", type=int_in(0, MAX_PER_CONFIG), metavar="N",
                        help=f"{when}: the best solutions within the force bound are rolled out again in N fresh worlds "
                             f"from each known start configuration and the best there is picked ({default}; 0: the "
                             "training success alone decides)")
    parser.add_argument("--validation-candidates", type=int_in(1, MAX_VALIDATION_CANDIDATES), metavar="K",
                        help="how many solutions the validation rolls out (default 3: the best by training success)")


def int_at_least(minimum: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {quote(text)}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {quote(value)}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


positive_int = int_at_least(1)


def int_in(minimum: int, maximum: int) -> Callable[[str], int]:
    at_least = int_at_least(minimum)

    def parse(text: str) -> int:
        value = at_least(text)
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum}, got {quote(value)}")
        return value

    parse.__name__ = f"integer in [{minimum}, {maximum}]"
    return parse


def nonnegative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {quote(text)}") from None
    if not (value >= 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text if len(text) <= QUOTE_CHARS else quote(text)}")
    return value


def setting_type(setting) -> Callable[[str], Any]:
    """The argparse type of a run setting (``mjxskill.runs.settings.Setting``): the check
    config.yaml goes through too."""

    def parse(text: str):
        try:
            return setting.coerce(text)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    parse.__name__ = setting.name
    return parse


def seed_type() -> Callable[[str], int]:
    """``--seed`` of every command: an integer in the range of a run's seed."""
    # lazy: runs.settings loads the scenario package and mujoco (~0.3 s); plan's and explore's
    # --help (0.13 s) import this module and never build a --seed
    from mjxskill.runs.settings import SEED

    return setting_type(SEED)


def port(text: str) -> int:
    """A TCP port, 0 (any free one) to 65535."""
    value = int_at_least(0)(text)
    if value > 65535:
        raise argparse.ArgumentTypeError(f"must be a port number 0-65535, got {quote(value)}")
    return value
