"""``python -m mjxskill.train TASK``: learn the free parameters of a planned task.

Placeholder until the optimizer and the rollout land: it plans the task, prints the plan and
the parameters it would learn, says that training is not built yet and exits with code 2.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from mjxskill import cli

NOT_BUILT = 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mjxskill.train", description="Learn the free skill parameters of a task.")
    cli.add_task_argument(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    from mjxskill.plan import describe
    from mjxskill.scenario import load_scenario

    scn = load_scenario(args.task)
    print(describe(scn, scn.task))
    print(f"{build_parser().prog}: training is not built yet (planning works; see above)", file=sys.stderr)
    return NOT_BUILT


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
