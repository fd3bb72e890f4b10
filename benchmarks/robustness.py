"""The paper's protocol and the robust one side by side, on the same worlds (issue 43).

    python benchmarks/robustness.py confirm docs/experiments/peg docs/experiments/peg-robust
    python benchmarks/robustness.py fresh runs/push-0 --per-config 25
    python benchmarks/robustness.py report peg:docs/experiments/peg:docs/experiments/peg-robust \\
        push:docs/experiments/push:docs/experiments/push-robust --out docs/experiments/robustness.md

``confirm`` rolls the picks of an experiment of the paper's protocol out in the confirmation
worlds of an experiment of the robust protocol (``mjxskill.evaluation.confirmation``: the same
seed, stream and worlds per start configuration, so the paper's pick, the robust pick and the
operators' sets are compared on the very same worlds), one repetition at a time, into
``ROBUST/paper_picks_confirmation.json`` (a repetition done is kept: a killed run continues). The
committed paper experiment is read, never written.

``fresh`` rolls a robust run's pick (its race's winner) and the operators' sets out in
``--per-config`` worlds of every known and unseen start configuration, of a stream no other
step draws from (must-hold 4 of issue 43: the default run's pick in 100 fresh worlds).

``report`` writes the comparison (markdown and, beside it, JSON): per task the picks' success on
known and unseen start configurations, per repetition and pooled, against every operator set on
the same worlds, time to success, commanded force, front sizes, hypervolume against random
search, and the episodes each repetition spent (training, replication, validation or race).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mjxskill.engine.build import build_rollout
from mjxskill.evaluation.baselines import Candidates, evaluate_candidates
from mjxskill.evaluation.confirmation import STREAM
from mjxskill.experiment.directory import Experiment
from mjxskill.experiment.stats import finished_repetitions, summarize
from mjxskill.runs.atomic_write import write_json, write_text
from mjxskill.runs.run_task import load_run_task

PAPER_PICKS = "paper_picks_confirmation.json"


def confirm_paper_picks(paper: Path, robust: Path) -> dict:
    """Rolls ``paper``'s picks out in ``robust``'s confirmation worlds (see the module docstring)."""
    paper_exp, robust_exp = Experiment(paper), Experiment(robust)
    protocol = robust_exp.protocol()
    if not protocol.confirm_per_config:
        sys.exit(f"{robust} has no confirmation (confirm_per_config 0): nothing to compare on")
    config = paper_exp.config()
    reps = finished_repetitions(paper_exp, config, paper_exp.protocol())
    path = robust / PAPER_PICKS
    doc = json.loads(path.read_text()) if path.is_file() else {"paper": str(paper), "repetitions": {}}
    scn, task = load_run_task(paper_exp.optimizer, config)
    rollout = build_rollout(scn, task, "native", worlds=config.worlds, episode_seconds=config.episode_seconds)
    try:
        for r in reps:
            if str(r.seed) in doc["repetitions"] or r.pick.row is None:
                continue
            params = r.front.params[r.pick.row]
            ev = evaluate_candidates(rollout, Candidates(("paper_pick",), ("picked",), params[None]),
                                     protocol.confirm_per_config, r.seed, config.batch_size, stream=STREAM)
            times = np.where(np.isfinite(ev.world_seconds[0]), ev.world_seconds[0], config.episode_seconds)
            doc["repetitions"][str(r.seed)] = {
                "pareto_row": r.pick.row, "parameters": params.tolist(),
                "known": float(ev.success[0, ev.known].mean()), "unseen": float(ev.success[0, ~ev.known].mean()),
                "per_config": ev.success[0].tolist(), "full_episode_time_s": float(times.mean()),
                "peak_commanded_force_N": float(ev.peak_commanded_force[0])}
            write_json(path, doc)
            print(f"seed {r.seed}: paper pick {doc['repetitions'][str(r.seed)]['unseen']:.1%} unseen", flush=True)
    finally:
        rollout.close()
    return doc


FRESH_STREAM = 0xF2E5  # worlds of no other stream: training, evaluation, race, confirmation


def fresh_worlds(run_dir: Path, per_config: int, seed: int) -> dict:
    """The pick of a robust run (its race's winner, race.json) and the operators' sets in
    ``per_config`` fresh worlds from every known and unseen start configuration."""
    from mjxskill.evaluation.racing import raced_pick
    from mjxskill.runs.run_dir import Run

    run = Run(run_dir)
    config = run.config()
    front = run.front(config)
    raced = raced_pick(run.path, front)
    if raced is None:
        sys.exit(f"{run_dir} has no finished race (a run of the robust protocol's pick)")
    scn, task = load_run_task(run, config)
    names = ("picked", *task.manual_parameters)
    params = np.concatenate([front.params[raced[0]][None], np.array(list(task.manual_parameters.values()), np.float64)])
    rollout = build_rollout(scn, task, config.engine, worlds=config.worlds, episode_seconds=config.episode_seconds)
    try:
        ev = evaluate_candidates(rollout, Candidates(names, ("picked",) + ("manual",) * (len(names) - 1), params),
                                 per_config, seed, config.batch_size, stream=FRESH_STREAM)
    finally:
        rollout.close()
    out = {"run": str(run_dir), "pareto_row": raced[0], "per_config": per_config, "seed": seed,
           "known_worlds": int(per_config * ev.known.sum()), "unseen_worlds": int(per_config * (~ev.known).sum()),
           "candidates": {n: {"known": float(ev.success[i, ev.known].mean()),
                              "unseen": float(ev.success[i, ~ev.known].mean()) if (~ev.known).any() else None}
                          for i, n in enumerate(names)}}
    print(json.dumps(out, indent=1))
    return out


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def _episodes_paper(summary: dict) -> dict:
    p = summary["protocol"]
    validation = (p.get("validation_candidates") or 0) * (p.get("validation_per_config") or 0) * (p.get("known_configs") or 0)
    return {"training": p["budget"] * p["worlds"], "replication": 0, "pick": validation,
            "total": p["budget"] * p["worlds"] + validation}


def task_comparison(task: str, paper: Path, robust: Path) -> dict:
    """The numbers of one task's comparison (the JSON the markdown is written from)."""
    paper_s, robust_s = summarize(Experiment(paper)), summarize(Experiment(robust))
    confirmed = robust_s.get("confirmation", {})
    paper_picks = json.loads((robust / PAPER_PICKS).read_text())["repetitions"] if (robust / PAPER_PICKS).is_file() else {}
    seeds = [e["seed"] for e in confirmed.get("repetitions", [])]
    per_rep = []
    for e in confirmed.get("repetitions", []):
        row = {"seed": e["seed"], **{f"{name}_{side}": c[side] for name, c in e["candidates"].items()
                                     for side in ("known", "unseen")}}
        mine = paper_picks.get(str(e["seed"]))
        if mine is not None:
            row.update(paper_pick_known=mine["known"], paper_pick_unseen=mine["unseen"])
        per_rep.append(row)
    both = [s for s in seeds if str(s) in paper_picks]
    paper_pooled = {side: float(np.mean([paper_picks[str(s)][side] for s in both])) if both else None
                    for side in ("known", "unseen")}
    robust_eps = robust_s.get("episodes", [])
    return {
        "task": task, "paper_experiment": str(paper), "robust_experiment": str(robust),
        "repetitions": {"paper": paper_s["status"]["repetitions_done"], "robust": robust_s["status"]["repetitions_done"],
                        "compared": len(both)},
        "confirm_per_config": confirmed.get("per_config"),
        "pooled": {"paper_pick": {**paper_pooled,
                                  "lowest_unseen": min((paper_picks[str(s)]["unseen"] for s in both), default=None),
                                  "full_episode_time_s": _mean([paper_picks[str(s)]["full_episode_time_s"] for s in both]),
                                  "peak_commanded_force_N": _mean([paper_picks[str(s)]["peak_commanded_force_N"]
                                                                   for s in both])},
                   **{name: p for name, p in confirmed.get("pooled", {}).items()}},
        "per_repetition": per_rep,
        "evaluation": {"paper": paper_s["groups"].get("picked"), "robust": robust_s["groups"].get("picked")},
        "front_size": {"paper": paper_s["front_size"]["mean"], "robust": robust_s["front_size"]["mean"]},
        "hypervolume_vs_random_p": {"paper": paper_s["hypervolume"]["mann_whitney_p_final"],
                                    "robust": robust_s["hypervolume"]["mann_whitney_p_final"]},
        "hypervolume": {"paper": {k: paper_s["hypervolume"][k] for k in ("optimizer", "random_search")},
                        "robust": {k: robust_s["hypervolume"][k] for k in ("optimizer", "random_search")}},
        "episodes": {"paper": _episodes_paper(paper_s),
                     "robust": {k: _mean([e[k] for e in robust_eps]) for k in ("training", "replication", "race", "total")}
                     if robust_eps else None},
        "wall_time_s": {"paper": _wall(paper_s), "robust": _wall(robust_s)},
    }


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _wall(summary: dict) -> float:
    """Seconds of every repetition's runs, evaluation and pick, summed (report's wall-time table)."""
    keys = ("train_seconds", "evaluate_seconds", "validate_seconds", "race_seconds", "confirm_seconds")
    return float(sum(kinds[kind].get(k, 0.0) for kinds in summary["wall_time"].values()
                     for kind in ("optimizer", "random_search") for k in keys))


def markdown(comparisons: list[dict]) -> str:
    lines = ["# The paper's protocol and the robust one, side by side", "",
             "Generated by `python benchmarks/robustness.py report` from the committed experiments. Every success "
             "rate below that is marked *confirmed* comes from the same fresh worlds for the paper protocol's pick, "
             "the robust protocol's pick and the operators' illustrative sets of a repetition (the robust "
             "experiment's confirmation worlds: 20 per start configuration, known and unseen).", ""]
    for c in comparisons:
        pooled = c["pooled"]
        names = [n for n in pooled if n not in ("paper_pick",)]
        lines += [f"## {c['task']}", "",
                  f"Repetitions: paper {c['repetitions']['paper']}, robust {c['repetitions']['robust']}, compared on "
                  f"the same worlds {c['repetitions']['compared']}.", "",
                  "| confirmed, pooled over the repetitions | known | unseen | lowest repetition, unseen | time to "
                  "success (failure = full episode) | commanded force |", "|---|---|---|---|---|---|"]
        for name, label in (("paper_pick", "paper protocol's pick"), *((n, "robust protocol's pick" if n == "picked"
                                                                         else f"{n} (illustrative)") for n in names)):
            p = pooled.get(name) or {}
            lines.append(f"| {label} | {_pct(p.get('known'))} | {_pct(p.get('unseen'))} | {_pct(p.get('lowest_unseen'))} "
                         f"| {_num(p.get('full_episode_time_s'), '{:.2f} s')} | {_num(p.get('peak_commanded_force_N'), '{:.2f} N')} |")
        ops = [n for n in names if n != "picked"]
        lines += ["", "| seed | paper pick known / unseen | robust pick known / unseen | "
                  + " | ".join(f"{n} known / unseen" for n in ops) + " |", "|---|---|---|" + "---|" * len(ops)]
        for r in c["per_repetition"]:
            lines.append(f"| {r['seed']} | {_pct(r.get('paper_pick_known'))} / {_pct(r.get('paper_pick_unseen'))} | "
                         f"{_pct(r.get('picked_known'))} / {_pct(r.get('picked_unseen'))} | "
                         + " | ".join(f"{_pct(r.get(n + '_known'))} / {_pct(r.get(n + '_unseen'))}" for n in ops) + " |")
        e, f, hv = c["episodes"], c["front_size"], c["hypervolume_vs_random_p"]
        rob = e["robust"] or {}
        lines += ["", "| | paper protocol | robust protocol |", "|---|---|---|",
                  f"| picks in the experiment's own evaluation (5 worlds per configuration), known / unseen | "
                  f"{_pct((c['evaluation']['paper'] or {}).get('known'))} / {_pct((c['evaluation']['paper'] or {}).get('unseen'))} | "
                  f"{_pct((c['evaluation']['robust'] or {}).get('known'))} / {_pct((c['evaluation']['robust'] or {}).get('unseen'))} |",
                  f"| Pareto front size (mean) | {_num(f['paper'], '{:.1f}')} | {_num(f['robust'], '{:.1f}')} |",
                  f"| hypervolume above random search's, Mann-Whitney p | {_num(hv['paper'], '{:.3g}')} | {_num(hv['robust'], '{:.3g}')} |",
                  f"| episodes per repetition: training | {e['paper']['training']} | {_num(rob.get('training'), '{:.0f}')} |",
                  f"| rolled out again during training | 0 | {_num(rob.get('replication'), '{:.0f}')} |",
                  f"| the pick's validation / race | {e['paper']['pick']} | {_num(rob.get('race'), '{:.0f}')} |",
                  f"| total, of the paper's budget x worlds | {e['paper']['total']} | {_num(rob.get('total'), '{:.0f}')} |",
                  f"| wall time, all repetitions (this machine, shared) | {c['wall_time_s']['paper']:.0f} s | "
                  f"{c['wall_time_s']['robust']:.0f} s |", ""]
    return "\n".join(lines)


def _num(v, fmt: str) -> str:
    return "-" if v is None else fmt.format(v)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("confirm", help="roll a paper experiment's picks out in a robust experiment's confirmation worlds")
    c.add_argument("paper", type=Path)
    c.add_argument("robust", type=Path)
    f = sub.add_parser("fresh", help="a robust run's pick and the operators' sets in fresh worlds")
    f.add_argument("run", type=Path)
    f.add_argument("--per-config", type=int, default=25)
    f.add_argument("--seed", type=int, default=0)
    f.add_argument("--save", type=Path)
    r = sub.add_parser("report", help="write the side-by-side comparison")
    r.add_argument("pairs", nargs="+", metavar="TASK:PAPER_DIR:ROBUST_DIR")
    r.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.command == "confirm":
        confirm_paper_picks(args.paper, args.robust)
        return 0
    if args.command == "fresh":
        result = fresh_worlds(args.run, args.per_config, args.seed)
        if args.save:
            write_json(args.save, result)
        return 0
    comparisons = []
    for pair in args.pairs:
        task, paper, robust = pair.split(":")
        comparisons.append(task_comparison(task, Path(paper), Path(robust)))
    write_text(args.out, markdown(comparisons))
    write_json(args.out.with_suffix(".json"), comparisons)
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
