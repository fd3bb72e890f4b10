"""evaluate: candidates, per-start-configuration success rates (with a scripted stand-in for
the rollout), Mann-Whitney stars, the CSV, table and box plot."""

import csv
from types import SimpleNamespace

import numpy as np
import pytest

from mjxskill.task import plan_task
from mjxskill.evaluation.baselines import (
    Candidates,
    build_candidates,
    evaluate_candidates,
    plot_boxes,
    significance,
    table,
    write_csv,
)


def test_candidates_are_pareto_planner_random_and_manual(push):
    front = np.array([[0.1, 0.1, -0.1, 0.0], [0.0, 0.2, 0.0, -0.2]])
    task = plan_task(push)
    c = build_candidates(task, front, n_random=10, seed=0)
    assert c.names[:3] == ("pareto-0", "pareto-1", "planner")
    assert c.groups.count("pareto") == 2 and c.groups.count("random") == 10
    assert c.groups.count("manual") == len(task.manual_parameters) == len(push.manual_parameters) == 3
    np.testing.assert_array_equal(c.params[:2], front)
    np.testing.assert_array_equal(c.params[2], task.defaults)
    for name, manual in push.manual_parameters.items():
        np.testing.assert_array_equal(c.params[c.names.index(name)], [manual.values[n] for n in task.parameter_names])
    lo, hi = task.bounds
    random = c.params[[g == "random" for g in c.groups]]
    assert np.all((random >= lo) & (random <= hi)) and len(np.unique(random, axis=0)) == 10
    np.testing.assert_array_equal(build_candidates(task, front, 10, seed=0).params, c.params)  # reproducible


class ScriptedRollout:
    """Stands in for a compiled rollout. World w of a (C * K,) configuration-major world set
    succeeds for candidate p when its replicate index r = w % K is below
    k(p, c) = (round(10 p_0) + c) % (K + 1), c = w // K counted over known then unseen configs,
    so the expected rate from configuration c is k(p, c) / K."""

    def __init__(self, n_known, n_unseen, per_config):
        self.scenario = SimpleNamespace(robot=SimpleNamespace(start_configs=np.zeros((n_known, 7)), eval_configs=np.ones((n_unseen, 7))))
        self.per_config, self.batches = per_config, []

    def worlds_per_config(self, key, per_config, configs):
        n = len(configs) * per_config
        return SimpleNamespace(config_index=np.repeat(np.arange(len(configs)), per_config), arm_qpos=np.zeros((n, 7)))

    def run_worlds(self, params, worlds):
        self.batches.append(len(params))
        k_cfg = self.per_config
        n = len(worlds.config_index)
        w = np.arange(n)
        k = (np.round(10 * params[:, :1]).astype(int) + w // k_cfg) % (k_cfg + 1)
        return SimpleNamespace(success=(w % k_cfg) < k, metrics={"position_error": np.broadcast_to(0.001 * w, k.shape)})


def expected_rate(p0, c, per_config):
    return ((round(10 * p0) + c) % (per_config + 1)) / per_config


def test_success_per_start_configuration_known_and_unseen(monkeypatch):
    import jax

    # The stand-in returns plain namespaces: concatenate them field by field like Worlds.
    monkeypatch.setattr(jax, "tree", SimpleNamespace(map=lambda f, *xs: SimpleNamespace(
        config_index=f(*(x.config_index for x in xs)), arm_qpos=f(*(x.arm_qpos for x in xs)))))
    rollout = ScriptedRollout(n_known=4, n_unseen=2, per_config=3)
    params = np.array([[0.0], [0.1], [0.2], [0.3], [0.5], [0.7], [1.0]])
    cands = Candidates(tuple(f"c{i}" for i in range(7)), ("pareto",) * 7, params)
    ev = evaluate_candidates(rollout, cands, per_config=3, seed=0, batch_size=4)
    assert rollout.batches == [4, 4]  # always the same batch size: one compile
    expected = np.array([[expected_rate(p, c, 3) for c in range(6)] for p in params[:, 0]])
    np.testing.assert_allclose(ev.success, expected)
    assert ev.config_names == ("known-0", "known-1", "known-2", "known-3", "unseen-0", "unseen-1")
    np.testing.assert_allclose(ev.mean(True), expected[:, :4].mean(1))
    np.testing.assert_allclose(ev.mean(False), expected[:, 4:].mean(1))
    # world w has error 1 mm * w: configuration c's mean is 1 mm * (3c + 1)
    np.testing.assert_allclose(ev.position_error, np.broadcast_to(0.001 * (3 * np.arange(6) + 1), (7, 6)))


def test_significance_stars_against_exact_mann_whitney():
    # Completely separated samples of 4 and 4: exact two-sided p = 2 / C(8, 4) = 0.02857.
    p, stars = significance(np.array([0.1, 0.2, 0.3, 0.4]), np.array([0.6, 0.7, 0.8, 0.9]))
    assert p == pytest.approx(2 / 70) and stars == "**"  # the paper's levels: < 0.1, 0.05, 0.01, 0.001
    # 3 vs 3 completely separated: exact p = 2 / C(6, 3) = 0.1, not below the first level
    assert significance(np.array([1.0, 2, 3]), np.array([4.0, 5, 6])) == (pytest.approx(0.1), "ns")
    # 4 vs 3: 2 / C(7, 3) = 0.0571: one star
    assert significance(np.array([1.0, 2, 3, 4]), np.array([5.0, 6, 7])) == (pytest.approx(2 / 35), "*")
    p, stars = significance(np.ones(12), np.zeros(12))
    assert p < 0.001 and stars == "****"
    assert significance(np.full(5, 0.5), np.full(4, 0.5)) == (1.0, "ns")


def test_stars_at_the_paper_levels():
    from mjxskill.evaluation.baselines import stars_of

    assert [stars_of(p) for p in (0.2, 0.1, 0.099, 0.05, 0.049, 0.01, 0.0099, 0.001, 0.0009)] == \
        ["ns", "ns", "*", "*", "**", "**", "***", "***", "****"]


def test_csv_table_and_box_plot(tmp_path):
    from mjxskill.evaluation.baselines import Evaluation

    names = ("pareto-0", "pareto-1", "planner", "random-0", "random-1", "operator_a")
    groups = ("pareto", "pareto", "planner", "random", "random", "manual")
    success = np.array([[1, 1, 0.8, 1, 0.6], [1, 0.8, 1, 1, 0.4], [0, 0.2, 0, 0, 0], [0, 0, 0, 0.2, 0], [0, 0, 0, 0, 0], [0.4, 0.6, 0.2, 0.4, 0]])
    ev = Evaluation(Candidates(names, groups, np.arange(12.0).reshape(6, 2)), success, np.array([1, 1, 1, 1, 0], bool),
                    ("known-0", "known-1", "known-2", "known-3", "unseen-0"))
    tests = plot_boxes(ev, tmp_path / "success.png", "toy")
    assert (tmp_path / "success.png").stat().st_size > 10_000
    assert set(tests) == {(lab, g) for lab in ("known", "unseen") for g in ("planner", "random", "manual")}
    assert tests[("known", "random")][1] == "****"  # 8 samples of ~1 vs 8 of ~0
    write_csv(ev, ("S.a", "S.b"), tmp_path / "e.csv")
    with open(tmp_path / "e.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["candidate"] for r in rows] == list(names)
    assert float(rows[0]["success_known"]) == pytest.approx(0.95) and float(rows[0]["success_unseen"]) == 0.6
    assert float(rows[5]["success_known-1"]) == 0.6 and float(rows[1]["S.b"]) == 3.0
    text = table(ev, tests)
    assert "Pareto (learned)" in text and "operators" in text and "known p=" in text
