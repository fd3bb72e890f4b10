"""benchmarks/mobo_priors.py's report of saved runs: files merged by seed, the regret about the
reference the same seed's no-prior run infers (against a closed form on ZDT1), and clear
errors for files that do not merge."""

import json
import re
import os
import subprocess
import sys

import numpy as np
import pytest

BENCHMARKS = os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks")
sys.path.insert(0, BENCHMARKS)
import mobo_priors as mp  # noqa: E402

ARGS = {"budget": 3, "batch": 1, "init": 2, "std_fraction": 0.15, "given_ref": False, "option": []}
# ZDT1's two ends of the front: as the warm-up (init 2) they set the reference to [1.1, 1.1]
# (worst 1 plus 10 % of the range 1).
ENDS = [[0.0, 1.0], [1.0, 0.0]]


def zdt1_regret_of_the_ends(r: float) -> float:
    """% of ZDT1's front hypervolume about [r, r] (r >= 1) that the two ends alone miss: they
    dominate r^2 - 1, the whole front (r - 1) + 2/3 + (r - 1) r = r^2 - 1/3."""
    return 100.0 * (1.0 - (r * r - 1.0) / (r * r - 1.0 / 3.0))


def save(path, runs, args=ARGS, problem="ZDT1 (d=6)"):
    with open(path, "w") as fh:
        json.dump({"args": args, "problems": {problem: {"runs": runs}}}, fh)
    return str(path)


def test_regret_about_the_no_prior_runs_reference_against_a_closed_form(tmp_path, capsys):
    # The "good" run reaches f1 = 0.25 on the front as its third point; its own warm-up would
    # infer another reference, but the regret is taken about the no-prior run's of that seed.
    none = {"seed": 0, "y": ENDS + [[0.5, 5.0]]}  # a third point the ends dominate
    good = {"seed": 0, "y": [[0.0, 1.0], [3.0, 3.0], [0.25, 0.5]]}
    result = mp.report(mp.load_saved([save(tmp_path / "a.json", {"none": [none], "good": [good]})]))["ZDT1 (d=6)"]
    assert result["none"]["regret"][0, 0] == pytest.approx(zdt1_regret_of_the_ends(1.1), rel=1e-9)
    # good's points about [1.1, 1.1]: (3, 3) lies outside; (0, 1) and (0.25, 0.5) dominate two
    # boxes, 1.1 x 0.1 and 0.85 x 0.6, which overlap in 0.85 x 0.1.
    dominated = 1.1 * 0.1 + (1.1 - 0.25) * (1.1 - 0.5) - (1.1 - 0.25) * 0.1
    whole = 1.1**2 - 1.0 / 3.0
    assert result["good"]["regret"][0, 0] == pytest.approx(100.0 * (1.0 - dominated / whole), rel=1e-9)
    assert "regret at 3:" in capsys.readouterr().out


def test_files_merge_by_seed_and_a_reproduced_run_is_kept_once(tmp_path):
    a = save(tmp_path / "a.json", {"none": [{"seed": 0, "y": ENDS + [[0.5, 5.0]]}]})
    b = save(tmp_path / "b.json", {"none": [{"seed": 0, "y": ENDS + [[0.5, 5.0]]}, {"seed": 1, "y": ENDS + [[2.0, 2.0]]}]})
    runs = mp.load_saved([a, b])["problems"]["ZDT1 (d=6)"]["runs"]["none"]
    assert [r["seed"] for r in runs] == [0, 1]
    result = mp.report({"problems": mp.load_saved([a, b])["problems"]})["ZDT1 (d=6)"]["none"]
    np.testing.assert_allclose(result["regret"][:, 0], zdt1_regret_of_the_ends(1.1), rtol=1e-9)


@pytest.mark.parametrize("second, message", [
    ({"none": [{"seed": 0, "y": ENDS + [[0.6, 5.0]]}]}, "seed 0 is saved twice, with different values"),
    ({"none": [{"seed": "0", "y": ENDS}]}, "expected 'seed' (an integer)"),
    ({"none": [{"seed": 2, "y": [1.0, 2.0]}]}, "'y' is not an (n, m) table"),
])
def test_runs_that_do_not_merge_are_named(tmp_path, second, message):
    a = save(tmp_path / "a.json", {"none": [{"seed": 0, "y": ENDS + [[0.5, 5.0]]}]})
    b = save(tmp_path / "b.json", second)
    with pytest.raises(ValueError, match=r"b\.json: ZDT1 \(d=6\) / none") as e:
        mp.load_saved([a, b])
    assert message in str(e.value)


def test_different_settings_and_foreign_files_are_named(tmp_path):
    a = save(tmp_path / "a.json", {"none": [{"seed": 0, "y": ENDS + [[0.5, 5.0]]}]})
    b = save(tmp_path / "b.json", {"none": [{"seed": 1, "y": ENDS + [[0.5, 5.0]]}]}, args=dict(ARGS, given_ref=True))
    (tmp_path / "c.json").write_text('{"problems": []}')
    for files, message in [([a, b], "b.json: problem 'ZDT1 (d=6)' was run with given_ref = True, but"),
                           ([str(tmp_path / "c.json")], "c.json: not a result of mobo_priors.py --save")]:
        with pytest.raises(ValueError, match=re.escape(message)):
            mp.load_saved(files)


def test_a_bad_file_exits_2_from_the_command_line_without_a_traceback(tmp_path):
    (tmp_path / "d.json").write_text("not json")
    done = subprocess.run([sys.executable, os.path.join(BENCHMARKS, "mobo_priors.py"), "--report", str(tmp_path / "d.json")],
                          capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert "d.json: not JSON" in done.stderr and "Traceback" not in done.stderr


def test_a_setting_saved_before_the_no_prior_runs_is_compared_with_them(tmp_path):
    # The file's order of settings is the command line's (--settings good,none): the p value
    # against no prior must not depend on it.
    none = [{"seed": s, "y": ENDS + [[0.5, 5.0]]} for s in range(3)]
    good = [{"seed": s, "y": ENDS + [[0.25, 0.5]]} for s in range(3)]
    first = mp.report(mp.load_saved([save(tmp_path / "a.json", {"good": good, "none": none})]))["ZDT1 (d=6)"]
    second = mp.report(mp.load_saved([save(tmp_path / "b.json", {"none": none, "good": good})]))["ZDT1 (d=6)"]
    np.testing.assert_array_equal(first["good"]["regret"], second["good"]["regret"])
    assert (first["good"]["regret"] < first["none"]["regret"]).all()


def test_the_held_out_priors_good_on_the_front_and_misleading_where_objectives_are_poor():
    for name in mp.HELD_OUT_PROBLEMS:
        problem = mp.GP_PROBLEMS_BY_NAME[name]
        priors = mp.gp_priors(name, problem["d"], 0.15)
        good, bad = (np.asarray(priors[k].mean[0]) for k in ("good", "misleading"))
        assert good.shape == bad.shape == (problem["d"],) and priors["none"] is None
        if name.startswith(("ZDT2", "ZDT3")):
            assert np.all(good[1:] == 0.0) and np.all(bad[1:] == 1.0)  # g = 1 (the front) and g = 10
        if name.startswith("DTLZ2"):  # on the unit sphere, and beyond it by 1 + g = 1.75
            assert np.linalg.norm(problem["f"](good[None])) == pytest.approx(1.0)
            assert np.linalg.norm(problem["f"](bad[None])) == pytest.approx(1.75)
        worse = mp.percentile_of(problem, bad, n=20_000)
        if name.startswith("ZDT"):  # f1 = x1 = 0.5, f2 worse than nearly every draw
            assert worse[1] > 99.0
        else:  # worse than 70 % of the draws in every objective
            assert min(worse) > 70.0


def test_the_log_gap_in_decades_and_a_problem_without_a_front(tmp_path, capsys):
    assert mp.log_gap(100.0, 99.0) == pytest.approx(0.0)
    assert mp.log_gap(100.0, 90.0) == pytest.approx(1.0)
    # CarSideImpact has no front to take a run's own regret by: the gap is about its reference.
    y = [[30.0, 4.0, 12.0, 1.0], [40.0, 4.4, 13.0, 5.0]]
    args = dict(ARGS, budget=2, init=1)
    result = mp.report(mp.load_saved([save(tmp_path / "c.json", {"none": [{"seed": 0, "y": y}]}, args, "CarSideImpact")]))
    o = result["CarSideImpact"]["none"]
    assert len(o["regret"]) == 0 and len(o["log_gap"]) == 0
    hv = mp.hypervolume(np.asarray(y), mp.GP_PROBLEMS_BY_NAME["CarSideImpact"]["ref"])
    assert o["log_gap_problem_ref"][0, -1] == pytest.approx(np.log10(484.7265 - hv))
    assert "no regret about a run's own reference" in capsys.readouterr().out
