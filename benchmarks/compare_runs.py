"""Hypervolume of several runs of one task in one objective space, at equal evaluation counts.

    python benchmarks/compare_runs.py runs/push-native runs/push-mjx            # the first run's reference
    python benchmarks/compare_runs.py runs/a runs/b --reference-of runs/b --at 48,100,200,400

Each run's hypervolume (docs/walkthrough.md) uses the reference point its own warm-up fixed
(``run_state.json``), so two runs' curves are not comparable as printed. Here every run is
measured against one reference point, that of ``--reference-of`` (default: the first run), in
the optimizer's space (negated objectives), after the first N evaluations in batch order.
Used for issue 12's comparison of a default run on each engine (benchmarks/RESULTS.md).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run directories of the same task")
    parser.add_argument("--reference-of", type=Path, help="the run whose reference point is used (default: the first)")
    parser.add_argument("--at", default="48,100,200,252,300,400", help="evaluation counts, comma-separated")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)

    from mjxskill.gp import hypervolume
    from mjxskill.training.front import reference_from
    from mjxskill.runs.run_dir import Run

    def loaded(path: Path):
        run = Run(path)
        config = run.config()
        return run, config, run.evaluations(config)

    reference_run, reference_config, reference_ev = loaded(args.reference_of or args.runs[0])
    ref = reference_from(reference_run, reference_config, reference_ev, store=False)
    if ref is None:
        raise SystemExit(f"{reference_run.path}: its warm-up is not complete, so it has no reference point yet")
    counts = [int(c) for c in args.at.split(",")]
    result = {"reference_of": str(reference_run.path), "reference": ref.tolist(), "runs": {}}
    print(f"reference point {ref.tolist()} (of {reference_run.path}, negated objectives)")
    for path in args.runs:
        _, config, ev = loaded(path)
        if tuple(config.objective_names) != tuple(reference_config.objective_names):
            raise SystemExit(f"{path} has objectives {config.objective_names}, not {reference_config.objective_names}")
        hv = {n: hypervolume(-ev.objectives[:n], ref) for n in counts if n <= len(ev.objectives)}
        result["runs"][str(path)] = {"engine": config.engine, "evaluations": len(ev.objectives), "hypervolume": hv}
        print(f"{str(path):40s} {config.engine:7s} " + "  ".join(f"{n}: {v:,.1f}" for n, v in hv.items()))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
