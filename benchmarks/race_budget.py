"""How many episodes the robust protocol's race needs (issue 43): the measurements behind
``training_protocol.TRAINING_SHARE``.

    python benchmarks/race_budget.py grid --out benchmarks/results/2026-12-06/peg_grid.json
    python benchmarks/race_budget.py matrix RUN_DIR --out benchmarks/results/2026-12-06/peg_front_matrix.npz
    python benchmarks/race_budget.py simulate benchmarks/results/2026-12-06/peg_front_matrix.npz
    python benchmarks/race_budget.py pool docs/experiments/peg-robust-approach5mm --out DIR [--first-round-per-config N]

``grid``: the peg's success over a grid of force, spiral radius and path velocity, every set in
the same 150 worlds (10 from each of the 15 start configurations, key 11): the shape of the
success landscape. ``matrix``: the best front members of a run (by success bound) and the
operators' sets, each in the same 600 worlds of the known start configurations (120 each, key
555), every world's success and time kept. ``simulate``: successive halving, as
``mjxskill.evaluation.racing`` runs it, replayed on that matrix (each round's worlds drawn
without replacement per configuration) 400 times per race budget: the mean success of the
winner over the matrix's worlds, and how often it is the best set. ``pool``: each finished repetition of a robust experiment raced
again as ``mjxskill.evaluation.racing`` races (same settings, episodes and race worlds), but over
every current evaluation of its optimizer run instead of its front (the run's training is the
same either way, so only the race and the confirmation are rolled out); the winner confirmed in
the experiment's own confirmation worlds, beside ``operator_b`` (whose result must equal the
experiment's: the same worlds). ``--first-round-per-config N`` races only as many contenders
(best success bound first) as give the first round N worlds per known start configuration.
Resumable: each repetition's race and confirmation are kept under ``DIR/seed-S/``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mjxskill.evaluation.racing import schedule


def _rollout(task_name: str):
    from mjxskill.engine.build import build_rollout
    from mjxskill.runs.run_task import scenario_and_task

    scn, task = scenario_and_task(task_name, None)
    return scn, task, build_rollout(scn, task, "native", worlds=7, episode_seconds=scn.episode_seconds)


def _outcomes(rollout, params: np.ndarray, worlds, chunk: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """(success (N, W) bool, seconds to success (N, W), a failure the whole episode)."""
    success, seconds = [], []
    for start in range(0, len(params), chunk):
        out = rollout.run_worlds(params[start : start + chunk], worlds)
        won, tick = np.asarray(out.success), np.asarray(out.metrics["bt_done_tick"])
        success.append(won)
        seconds.append(np.where(won & (tick >= 0), (tick + 1) / rollout.scenario.bt_hz, rollout.episode_seconds))
        print(f"  {min(start + chunk, len(params))}/{len(params)} sets", flush=True)
    return np.concatenate(success), np.concatenate(seconds)


def grid(out: Path) -> None:
    import jax

    scn, _, rollout = _rollout("peg")
    configs = np.concatenate([np.asarray(scn.robot.start_configs), np.asarray(scn.robot.eval_configs)])
    worlds = rollout.worlds_per_config(jax.random.PRNGKey(11), 10, configs)
    params = np.array([(-f, r, v) for f in (4.0, 7.0, 10.0) for r in (0.03, 0.05) for v in (0.02, 0.035, 0.05, 0.065)])
    try:
        success, seconds = _outcomes(rollout, params, worlds)
    finally:
        rollout.close()
    rows = [{"force": float(p[0]), "radius": float(p[1]), "path_velocity": float(p[2]), "success": float(s.mean()),
             "time_to_success_full_episode_s": float(t.mean())} for p, s, t in zip(params, success, seconds)]
    out.write_text(json.dumps({"worlds": int(success.shape[1]), "key": 11, "sets": rows}, indent=1) + "\n")
    for r in rows:
        print(r)


def matrix(run_dir: Path, out: Path, count: int = 9) -> None:
    import jax

    from mjxskill.runs.run_dir import Run

    run = Run(run_dir)
    front = run.pareto(run.config())
    rows = [int(i) for i in np.argsort(-front.objectives[:, -1], kind="stable")[:count]]
    scn, task, rollout = _rollout(run.config().task)
    params = np.concatenate([front.params[rows], np.array(list(task.manual_parameters.values()), np.float64)])
    worlds = rollout.worlds_per_config(jax.random.PRNGKey(555), 120, np.asarray(scn.robot.start_configs))
    try:
        success, seconds = _outcomes(rollout, params, worlds)
    finally:
        rollout.close()
    np.savez(out, rows=rows, params=params, names=[f"pareto-{r}" for r in rows] + list(task.manual_parameters),
             success=success, seconds=seconds, per_config=120)
    print(dict(zip([f"pareto-{r}" for r in rows] + list(task.manual_parameters), success.mean(axis=1).round(3))))


def simulate(path: Path, budgets=(420, 700, 980, 1120, 1400), races: int = 400) -> dict:
    data = np.load(path)
    names = [str(n) for n in data["names"]]
    front = [i for i, n in enumerate(names) if n.startswith("pareto-")]
    success, seconds, per = data["success"].astype(float), data["seconds"], int(data["per_config"])
    n_configs = success.shape[1] // per
    truth = success.mean(axis=1)
    best = front[int(np.argmax(truth[front]))]
    out = {"sets": dict(zip(names, truth.round(4).tolist())), "races": races, "budgets": {}}
    for budget in budgets:
        rng = np.random.default_rng(0)
        winners = [_race(front, budget, success, seconds, per, n_configs, rng) for _ in range(races)]
        won = truth[winners]
        out["budgets"][budget] = {"winner_mean": float(won.mean()), "best_picked": float(np.mean(np.array(winners) == best)),
                                  "winner_5th_percentile": float(np.percentile(won, 5))}
        print(budget, out["budgets"][budget], flush=True)
    return out


def _race(rows, budget: int, success, seconds, per: int, n_configs: int, rng) -> int:
    """One successive-halving race over ``rows`` (the racing module's schedule and ranking)."""
    k, plan = schedule(len(rows), n_configs, budget)
    alive = list(rows[:k])
    won, worlds, time = dict.fromkeys(alive, 0.0), dict.fromkeys(alive, 0), dict.fromkeys(alive, 0.0)
    order = [rng.permutation(per) for _ in range(n_configs)]
    used = 0
    for index, (_, per_config) in enumerate(plan):
        cols = np.concatenate([c * per + order[c][used : used + per_config] for c in range(n_configs)])
        used += per_config
        for i in alive:
            won[i] += success[i, cols].sum()
            worlds[i] += len(cols)
            time[i] += seconds[i, cols].sum()
        keep = plan[index + 1][0] if index + 1 < len(plan) else 1
        alive = sorted(alive, key=lambda i: (-won[i] / worlds[i], time[i] / worlds[i], i))[:keep]
    return alive[0]


def pool(exp_dir: Path, out: Path, first_round_per_config: int = 1) -> dict:
    from mjxskill.engine.build import build_rollout
    from mjxskill.evaluation import racing
    from mjxskill.evaluation.baselines import Candidates
    from mjxskill.evaluation.confirmation import confirm, load_confirmation
    from mjxskill.experiment.directory import (
        Experiment,
        repetition_confirmation,
        repetition_race,
    )
    from mjxskill.experiment.picks import picked_repetition
    from mjxskill.runs.run_task import load_run_task

    exp = Experiment(exp_dir)
    config, protocol = exp.config(), exp.protocol()
    scn, task = load_run_task(exp.optimizer, config)
    n_known = len(scn.robot.start_configs)
    rollout = build_rollout(scn, task, config.engine, worlds=1, episode_seconds=config.episode_seconds)
    operator = np.asarray(task.manual_parameters["operator_b"], np.float64)
    result = {"experiment": str(exp_dir), "first_round_per_config": first_round_per_config, "repetitions": []}
    try:
        for i, (opt, _) in enumerate(exp.runs(config)):
            seed = config.seed + i
            picked = picked_repetition(exp, config, protocol, i)
            if picked is None:
                continue
            front, raced = picked[2], picked[6]
            confirmation = repetition_confirmation(config, protocol, seed)
            own = load_confirmation(opt.path, None, confirmation)
            if own is None:
                continue
            ev = opt.evaluations(opt.config())
            current = ev.take(np.flatnonzero(ev.current()))
            settings = repetition_race(config, protocol, seed, n_known)
            rows = racing.contenders(current, settings["max_force"])
            # the race's own rule for K, with the first round's worlds per configuration asked for
            k = max(1, schedule(len(rows), n_known * first_round_per_config, settings["episodes"])[0])
            pool_of = current.take(np.array(sorted(rows[:k])))  # contenders() orders them again
            here = out / f"seed-{seed}"
            here.mkdir(parents=True, exist_ok=True)
            won = racing.race(here, pool_of, rollout, settings, batch_size=6)
            params = pool_of.params[won.winner]
            candidates = Candidates(("picked", "operator_b"), ("picked", "manual"), np.stack([params, operator]))
            conf, _ = confirm(here, rollout, candidates, confirmation, batch_size=2)
            b = own.candidates.names.index("operator_b")
            assert np.array_equal(conf.success[1], own.success[b]), "not the experiment's confirmation worlds"
            old = own.success[0]
            row = {"seed": seed, "pool": len(rows), "contenders": len(won.contenders),
                   "rounds": [[len(r.rows), r.worlds] for r in won.rounds], "episodes": won.episodes,
                   "winner_params": params.tolist(), "winner_race": list(won.race_success(won.winner)),
                   "winner_worlds_in_training": int(pool_of.worlds[won.winner]),
                   "winner_on_front": bool(any(np.array_equal(params, p) for p in front.params)),
                   "front_pick_params": front.params[raced.winner].tolist(),
                   "known": float(conf.success[0, conf.known].mean()), "unseen": float(conf.success[0, ~conf.known].mean()),
                   "front_pick_known": float(old[own.known].mean()), "front_pick_unseen": float(old[~own.known].mean()),
                   "operator_b_known": float(conf.success[1, conf.known].mean()),
                   "operator_b_unseen": float(conf.success[1, ~conf.known].mean())}
            result["repetitions"].append(row)
            print(json.dumps(row), flush=True)
    finally:
        rollout.close()
    reps = result["repetitions"]
    for key in ("known", "unseen", "front_pick_known", "front_pick_unseen", "operator_b_known", "operator_b_unseen"):
        result[key] = float(np.mean([r[key] for r in reps])) if reps else None
    print({k: v for k, v in result.items() if k != "repetitions"})
    (out / "pool.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("grid")
    g.add_argument("--out", type=Path, required=True)
    m = sub.add_parser("matrix")
    m.add_argument("run", type=Path)
    m.add_argument("--out", type=Path, required=True)
    s = sub.add_parser("simulate")
    s.add_argument("matrix", type=Path)
    s.add_argument("--save", type=Path)
    p = sub.add_parser("pool")
    p.add_argument("experiment", type=Path)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--first-round-per-config", type=int, default=1)
    args = parser.parse_args(argv)
    if args.command == "pool":
        pool(args.experiment, args.out, args.first_round_per_config)
    elif args.command == "grid":
        grid(args.out)
    elif args.command == "matrix":
        matrix(args.run, args.out)
    else:
        result = simulate(args.matrix)
        if args.save:
            args.save.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
