"""Garbage in XLA_FLAGS is one ``error:`` line naming XLA_FLAGS and the token, exit 2, not XLA's
fatal abort, on either engine: checked by the command line before jax reads them."""

import string

from hypothesis import given, settings, strategies as st

from cli_helpers import error_line, invoke, run_cli
from mjxskill._runtime import CPU_SETTINGS, xla_flags_problem


@settings(max_examples=100, deadline=None)
@given(st.text(alphabet=string.ascii_letters + string.digits + "-=_./", min_size=1, max_size=20))
def test_a_token_not_shaped_as_a_flag_is_refused_by_its_shape(token):
    if token.startswith("--") and token[2:3].isalpha() and all(c.isalnum() or c == "_" for c in token[2:].split("=")[0]):
        return  # shaped as a flag: XLA itself judges it (the probe)
    problem = xla_flags_problem(f"{CPU_SETTINGS[0][1]} {token}")
    assert problem is not None and problem.startswith("XLA_FLAGS: ") and repr(token)[:60] in problem


def test_mjxskills_own_flags_and_host_devices_need_no_probe():
    flags = " ".join(s for _, s in CPU_SETTINGS) + " --xla_force_host_platform_device_count=2"
    assert xla_flags_problem(flags) is None


def test_an_unknown_flag_and_a_bad_value_are_named_in_process(tmp_path, capsys, monkeypatch):
    for flags, said in (("--garbage_flag=1", "'--garbage_flag=1' is not a flag XLA knows"),
                        ("--xla_force_host_platform_device_count=abc", "has a value XLA cannot read")):
        monkeypatch.setenv("XLA_FLAGS", flags)
        code, err = invoke(capsys, "train", "push", "--engine", "native", "--out", tmp_path / "out")
        error_line(code, err, "train", said)
        assert not (tmp_path / "out").exists()


def test_garbage_xla_flags_are_one_error_line_on_the_native_engine(tmp_path):
    done = run_cli("train", "push", "--engine", "native", "--budget", "12", "--batch-size", "6", "--init", "6",
                   "--worlds", "2", "--episode-seconds", "3", "--out", tmp_path / "out", XLA_FLAGS="--garbage=1")
    error_line(done.returncode, done.stderr, "train", "XLA_FLAGS", "'--garbage=1'")
    assert "F1" not in done.stderr and not (tmp_path / "out").exists()
