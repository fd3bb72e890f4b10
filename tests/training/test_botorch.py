"""``train --optimizer botorch-qlognehvi``: BoTorch's qLogNEHVI as a run like any other. The loop
with a closed-form objective (the shared warm-up, proposals in the bounds that improve on the
warm-up's hypervolume, resuming to the same rows), its reference point against the closed form,
and the refusal without the extra (which needs no BoTorch)."""

import importlib.machinery
import sys
import types
from dataclasses import replace

import numpy as np
import pytest

from capabilities import require  # noqa: E402
from cli_helpers import error_line, invoke  # noqa: E402
from mjxskill.gp import hypervolume
from mjxskill.runs.run_dir import EVALUATIONS
from mjxskill.training import botorch_search
from mjxskill.training.extras import missing_extra
from mjxskill.training.loop import train
from toy_runs import CONFIG, Recorder, new_run, toy_objective  # noqa: E402

# batches of 4, 2 (the warm-up), then 4 and 4 from BoTorch
TOY = replace(CONFIG, budget=14, optimizer="botorch-qlognehvi")


def test_missing_extra_says_what_to_install(monkeypatch):
    # find_spec reads sys.modules first: None there is a module that is not installed, a module
    # object one that is (so the check does not depend on what this machine has)
    installed = types.ModuleType("botorch")
    installed.__spec__ = importlib.machinery.ModuleSpec("botorch", None)
    monkeypatch.setitem(sys.modules, "botorch", installed)
    monkeypatch.setitem(sys.modules, "torch", None)
    assert missing_extra("botorch-qlognehvi") == \
        "needs PyTorch, which is not installed: pip install 'mjxskill[botorch]'"
    monkeypatch.setitem(sys.modules, "botorch", None)
    assert "needs BoTorch and PyTorch, which are not installed" in missing_extra("botorch-qlognehvi")
    assert missing_extra("mobo") is None and missing_extra("optuna-tpe") is None


def test_the_reference_is_the_warm_ups_worst_less_a_tenth_of_its_range():
    y = np.array([[1.0, -3.0], [2.0, -1.0], [0.0, -2.0], [5.0, 9.0]])  # the last row: after a warm-up of 3
    ref = botorch_search.reference_point(replace(TOY, n_init=3), y)
    np.testing.assert_allclose(ref, [0.0 - 0.2, -3.0 - 0.2])


def test_without_the_extra_train_says_how_to_install_it(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "botorch", None)
    out = tmp_path / "never"
    code, err = invoke(capsys, "train", "push", "--budget", "12", "--init", "6", "--optimizer", "botorch-qlognehvi", "--out", out)
    error_line(code, err, "train", "--optimizer botorch-qlognehvi needs BoTorch", "pip install 'mjxskill[botorch]'")
    assert not out.exists()  # refused before the run directory is made


def test_it_proposes_after_the_shared_warm_up_improves_and_resumes_to_the_same_rows(tmp_path, monkeypatch):
    require("botorch")  # not in the test extra: torch is a multi-GB download
    tutorial = require("mjxskill.training.botorch_tutorial")  # imports BoTorch: only with the extra
    # a smaller search than the tutorial's: the same code, a fraction of the time
    for name, value in (("RESTARTS", 2), ("RAW_SAMPLES", 64), ("MAX_ITER", 30), ("MC_SAMPLES", 32)):
        monkeypatch.setattr(tutorial, name, value)
    random_config = replace(TOY, optimizer="random")
    random_rows = train(new_run(tmp_path, "random", random_config), random_config, toy_objective)
    full = new_run(tmp_path, "full", TOY)
    recorder = Recorder()
    ev = train(full, TOY, recorder)
    assert [len(x) for _, x in recorder.calls] == [4, 2, 4, 4]
    np.testing.assert_array_equal(ev.params[:6], random_rows.params[:6])  # the Bayesian optimizer's warm-up
    lo, hi = np.asarray(TOY.bounds)
    assert np.all((ev.params >= lo) & (ev.params <= hi))
    assert len({tuple(row) for row in ev.params[6:]}) == 8
    # about its own reference, qLogNEHVI's batches add hypervolume to the warm-up's
    ref = -botorch_search.reference_point(TOY, ev.objectives)
    assert hypervolume(-ev.objectives, ref) > hypervolume(-ev.objectives[:6], ref)
    cut = new_run(tmp_path, "cut", TOY)
    with pytest.raises(KeyboardInterrupt):  # a Ctrl-C during the fourth batch, BoTorch's second
        train(cut, TOY, Recorder(stop_after=3))
    second = Recorder()
    train(cut, TOY, second)
    assert [it for it, _ in second.calls] == [3]
    assert (cut.path / EVALUATIONS).read_text() == (full.path / EVALUATIONS).read_text()
