"""Property: every text mutation of a shipped scenario or of the skill library it includes (a key
dropped, a value of another type, a YAML tag, the text cut short, a byte added) either loads and
plans, or fails with one ``ScenarioError`` line that names the mutated file and where in it (the
key path and line; the line and column for text that is not YAML at all). Never another
exception, never a traceback."""

import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mjxskill.errors import ScenarioError, UserError
from mjxskill.scenario import load_scenario
from mjxskill.task import plan_task
import scenario_texts
from scenario_texts import library_text, shipped_text

TEXTS = {name: shipped_text(name).encode() for name in ("push", "peg")} | {"library": library_text().encode()}
KEY_LINE = re.compile(rb"^(\s*-?\s*)([A-Za-z_][\w.#-]*):(?:(\s+)(\S.*)?)?$")  # "key: value" and "key:"
VALUES = [b"zzz", b"[1, 2]", b"{a: 1}", b"null", b"-1", b"0", b"1e300", b".nan", b"true", b'"12"', b"''", b"[]"]
TAGS = [b"!kg ", b"!!python/name:os.system ", b"!!python/object/apply:os.system ", b"!!float ", b"!!int ",
        b"!!binary ", b"!!set ", b"!!str ", b"!!timestamp ", b"!!omap ", b"!!bool ", b"!!null "]


def key_lines(text: bytes) -> list[int]:
    return [i for i, line in enumerate(text.split(b"\n")) if KEY_LINE.match(line)]


@st.composite
def mutations(draw):
    name = draw(st.sampled_from(sorted(TEXTS)))
    text = TEXTS[name]
    lines = text.split(b"\n")
    kind = draw(st.sampled_from(["drop key", "retype", "tag", "cut", "byte"]))
    if kind in ("drop key", "retype", "tag"):
        i = draw(st.sampled_from(key_lines(text)))
        indent, key, space, value = KEY_LINE.match(lines[i]).groups()
        space = space or b" "
        if kind == "drop key":
            lines.pop(i)
        elif kind == "retype":
            lines[i] = indent + key + b":" + space + draw(st.sampled_from(VALUES))
        else:
            lines[i] = indent + key + b":" + space + draw(st.sampled_from(TAGS)) + (value or b"")
        mutated = b"\n".join(lines)
    elif kind == "cut":
        mutated = text[: draw(st.integers(0, len(text) - 1))]
    else:
        at = draw(st.integers(0, len(text)))
        mutated = text[:at] + bytes([draw(st.integers(0, 255))]) + text[at:]
    return name, kind, mutated


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=mutations())
def test_a_mutated_scenario_loads_or_names_file_and_place(tmp_path, case):
    name, kind, mutated = case
    path = tmp_path / f"{name}-mutated.yaml"
    path.write_bytes(mutated)
    scenario = path
    if name == "library":  # the peg scenario including the mutated library
        scenario = tmp_path / "peg.yaml"
        scenario.write_text(shipped_text("peg", path))
    try:
        scn = load_scenario(scenario)
    except ScenarioError as err:
        message = str(err)
        assert "\n" not in message, message
        if name == "library" and message.startswith(f"{scenario}"):
            path = scenario  # what the scenario asks of the library it no longer has (a skill, a parameter)
        if name != "library" and f"(as included by {path}," in message:
            path = scenario_texts.LIBRARY  # a library skill needs what the scenario lost (a predicate)
        assert message.startswith(f"{path}"), message
        # "file: key.path (line N): ..." or, for text that is no YAML document, "file (line N[, column M]): ..."
        assert re.match(rf"{re.escape(str(path))}(: \S.* \(line \d+\)| \(line \d+(, column \d+)?\)|): ", message), message
        if message.startswith(f"{path}: ") and " (line " not in message:  # no place in the file: the whole file
            assert re.search(r"the file is empty|larger than", message), message
        return
    try:  # loaded: planning its own goal may still find it unplannable, said the same way
        plan_task(scn)
    except UserError as err:
        assert "\n" not in str(err) and str(scenario) in str(err), str(err)


@pytest.mark.parametrize("name", sorted(TEXTS))
def test_every_key_line_is_a_mutation_site(name):
    # the strategy reaches the whole file: every top-level section has key lines
    text = TEXTS[name]
    top = {KEY_LINE.match(text.split(b"\n")[i]).group(2) for i in key_lines(text)}
    if name == "library":
        assert {b"skills", b"parameters", b"tree", b"children", b"args", b"primitive"} <= top
    else:
        assert {b"name", b"scene", b"robot", b"objects", b"skill_library", b"rewards", b"optimizer"} <= top
