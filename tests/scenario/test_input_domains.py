"""Values out of their domain, and the error text about them, as properties.

Values the simulator or the math cannot honour: every declared number of a scenario (the
world model's physics, the task's, the reward constants, the skill library's parameters) and
every acquisition setting has a domain (``mjxskill.scenario.domain``); a value outside it is one
located ``ScenarioError`` (file, key path, line) when the scenario loads, and from the command
line one ``error:`` line with exit code 2 and no run directory.

Errors that echo nothing they should not: an error line stays short however long the value
it names, and a file that is not what the scenario says it is (a skill library that is a secret
text file) is never shown.

Only scenarios are loaded and commands refused: no rollout, each example well under a second."""

import math
import re

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cli_helpers import error_line, invoke
from mjxskill.errors import MAX_MESSAGE_CHARS, ScenarioError, UserError
from mjxskill.gp.settings import MAXIMUM, NAMES, setting_value
from mjxskill.scenario import domain, load_scenario, schema
from mjxskill.scenario.domain import Domain
from mjxskill.scenario.vocabulary import CONSTANT_DOMAINS, REWARD_KINDS
from scenario_texts import library_text, shipped_text, write_library_copy

TEXTS = {"push": shipped_text("push"), "peg": shipped_text("peg"), "library": library_text()}
PEG_BOX_D_O = REWARD_KINDS["ee_distance_to_box"].domain("d_o")

# (text, the line as shipped, the line with {v} for the value, key path, the declared domain).
# One entry per declared numeric field of the scenarios and the skill library.
SITES = [
    ("push", "size: [0.15, 0.30, 0.07]", "size: [{v}, 0.30, 0.07]", "objects.ObjectToBePushed-1.size[0]", domain.SIZE),
    ("push", "size: [0.07, 0.07, 0.05]", "size: [0.07, {v}, 0.05]", "objects.Pusher-1.size[1]", domain.SIZE),
    ("peg", "size: [0.015, 0.05] ", "size: [{v}, 0.05] ", "objects.Peg-1.size[0]", domain.SIZE),
    ("peg", "size: [0.073, 0.073, 0.05]", "size: [0.073, 0.073, {v}]", "objects.BoxWithHole-1.size[2]", domain.SIZE),
    ("push", "mass: 2.5", "mass: {v}", "objects.ObjectToBePushed-1.mass", domain.MASS),
    ("push", "friction: 0.25", "friction: {v}", "objects.Pusher-1.friction", domain.FRICTION),
    ("push", "com_offset: [-0.02, 0.04, -0.005]", "com_offset: [-0.02, {v}, -0.005]",
     "objects.ObjectToBePushed-1.com_offset[1]", domain.POSITION),
    ("push", "position: [0.55, -0.20, 0.035]", "position: [{v}, -0.20, 0.035]",
     "objects.ObjectToBePushed-1.pose.position[0]", domain.POSITION),
    ("push", "rpy_deg: [0, 0, 26]", "rpy_deg: [0, 0, {v}]", "objects.ObjectGoalPose-1.pose.rpy_deg[2]", domain.ANGLE_DEG),
    ("push", "approach_offset: [0.0, -0.20, 0.09]", "approach_offset: [0.0, -0.20, {v}]",
     "objects.ObjectToBePushed-1.approach_offset[2]", domain.POSITION),
    ("peg", "hole_clearance: 0.0015", "hole_clearance: {v}", "objects.BoxWithHole-1.extra.hole_clearance", domain.EXTRA),
    ("peg", "hole_depth: 0.04", "hole_depth: {v}", "objects.BoxWithHole-1.extra.hole_depth", domain.EXTRA),
    ("push", "joint_limits_deg: [170,", "joint_limits_deg: [{v},", "robot.joint_limits_deg[0]", domain.JOINT_LIMIT_DEG),
    ("push", "nullspace_stiffness: 5.0", "nullspace_stiffness: {v}", "robot.nullspace_stiffness", domain.STIFFNESS),
    ("push", "default_stiffness: [400,", "default_stiffness: [{v},", "robot.default_stiffness[0]", domain.STIFFNESS),
    ("push", "objective: success, weight: 1.0,\n     object: ObjectToBePushed-1, target: ObjectGoalPose-1,\n     "
             "constants: {sigma_w: 0.4, d_o: 0.0, position_weight: 6.0",
     "objective: success, weight: 1.0,\n     object: ObjectToBePushed-1, target: ObjectGoalPose-1,\n     "
     "constants: {sigma_w: {v}, d_o: 0.0, position_weight: 6.0", "rewards[0].constants.sigma_w",
     CONSTANT_DOMAINS["sigma_w"]),
    ("push", "d_o: 0.0, position_weight: 6.0", "d_o: {v}, position_weight: 6.0", "rewards[0].constants.d_o",
     CONSTANT_DOMAINS["d_o"]),
    ("push", "position_weight: 6.0", "position_weight: {v}", "rewards[0].constants.position_weight",
     CONSTANT_DOMAINS["position_weight"]),
    ("push", "kind: object_pose_divergence, objective: success, weight: 1.0,\n     object: ObjectToBePushed-1, "
             "target: ObjectGoalPose-1,\n     constants: {sigma_w: 0.4, d_o: 0.0, position_weight: 6.0",
     "kind: object_pose_divergence, objective: success, weight: {v},\n     object: ObjectToBePushed-1, "
     "target: ObjectGoalPose-1,\n     constants: {sigma_w: 0.4, d_o: 0.0, position_weight: 6.0", "rewards[0].weight",
     domain.WEIGHT),
    ("peg", "constants: {value: 8.0}", "constants: {value: {v}}", "rewards[0].constants.value", CONSTANT_DOMAINS["value"]),
    ("peg", "constants: {w: 2.0, d_o: 0.006}", "constants: {w: {v}, d_o: 0.006}", "rewards[2].constants.w",
     CONSTANT_DOMAINS["w"]),
    ("peg", "constants: {w: 2.0, d_o: 0.006}", "constants: {w: 2.0, d_o: {v}}", "rewards[2].constants.d_o", PEG_BOX_D_O),
    ("peg", "target_offset: [0.0, 0.0, 0.01]", "target_offset: [0.0, 0.0, {v}]", "rewards[1].target_offset[2]",
     domain.POSITION),
    ("push", "position_tolerance: 0.01", "position_tolerance: {v}", "success.position_tolerance", domain.TOLERANCE),
    ("push", "orientation_tolerance_deg: 5.0", "orientation_tolerance_deg: {v}", "success.orientation_tolerance_deg",
     domain.ANGLE_TOLERANCE_DEG),
    ("peg", "  depth: 0.01", "  depth: {v}", "success.depth", domain.DEPTH),
    ("push", "xy_sigma: {ObjectToBePushed-1: 0.007", "xy_sigma: {ObjectToBePushed-1: {v}",
     "randomization.xy_sigma.ObjectToBePushed-1", domain.SIGMA),
    ("push", "friction_range: [0.2, 0.25]", "friction_range: [0.2, {v}]", "randomization.friction_range[1]",
     domain.FRICTION_RANGE),
    ("push", "max_force: 10.0", "max_force: {v}", "pick.max_force", domain.FORCE),
    ("push", "episode_seconds: 12.0", "episode_seconds: {v}", "episode_seconds",
     Domain(0.0, schema.MAX_EPISODE_SECONDS, exclusive_minimum=True)),
    ("library", "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [-0.3, 0.3]",
     "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [{v}, 0.3]",
     "skills.Push.parameters.offset_x_start.bounds[0]", domain.PARAMETER),
    ("library", "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [-0.3, 0.3]",
     "offset_x_start: {type: float, unit: m, default: 0.0, bounds: [-0.3, {v}]",
     "skills.Push.parameters.offset_x_start.bounds[1]", domain.PARAMETER),
    ("library", "push_height: {type: float, unit: m, default: 0.02", "push_height: {type: float, unit: m, default: {v}",
     "skills.Push.parameters.push_height.default", domain.PARAMETER),
    ("library", "stiffness: {type: vector, unit: \"N/m, Nm/rad\", default: [700,",
     "stiffness: {type: vector, unit: \"N/m, Nm/rad\", default: [{v},", "skills.Push.parameters.stiffness.default[0]",
     domain.PARAMETER),
]
# What a user might write out of a domain: YAML's spellings of the special floats, the extremes of
# a float, and values that end in a traceback where nothing checks them first.
SPECIAL = [".nan", ".inf", "-.inf", "1e308", "-1e308", "1e-300", "-1e-300", "1e30", "-1e30", "1e400", "0", "-0.0",
           "-1", "5e-324", "1" + "0" * 400]


def _number(text: str) -> float:
    return {".nan": math.nan, ".inf": math.inf, "-.inf": -math.inf}.get(text) or float(text)


values = st.one_of(st.sampled_from(SPECIAL),
                   st.floats(allow_nan=False, allow_infinity=False).map(repr).filter(lambda t: "e" in t or "." in t))


def line_of(text: str, fragment: str) -> int:
    assert text.count(fragment) == 1, fragment
    return text[: text.index(fragment)].count("\n") + 1


def mutated(tmp_path, site, value: str):
    """(scenario path, file the error must name, its text) with ``value`` at ``site``."""
    name, old, new, key, _ = site
    text = TEXTS[name]
    assert text.count(old) == 1, old
    edited = text.replace(old, new.replace("{v}", value))
    if name == "library":
        return write_library_copy(tmp_path, "peg" if "PegInsertion" in key else "push", edited), tmp_path / "library.yaml", edited
    path = tmp_path / f"{name}-edited.yaml"
    path.write_text(edited)
    return path, path, edited


@pytest.mark.parametrize("site", SITES, ids=[s[3] for s in SITES])
def test_every_site_loads_as_shipped(tmp_path, site):
    # each site's line is in the shipped text once, and the shipped value is inside its domain
    name, old, new, key, domain = site
    value = _shipped_value(old, new)
    assert domain.problem(_number(value)) is None, (key, value)
    path, _, text = mutated(tmp_path, site, value)
    load_scenario(path)


def _shipped_value(old: str, new: str) -> str:
    prefix, _, suffix = new.partition("{v}")
    assert old.startswith(prefix) and old.endswith(suffix), (old, new)
    return old[len(prefix): len(old) - len(suffix)]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(site=st.sampled_from(SITES), value=values)
def test_a_value_outside_its_declared_domain_is_one_located_error(tmp_path, site, value):
    name, old, new, key, domain = site
    assume(domain.problem(_number(value)) is not None)
    path, named, text = mutated(tmp_path, site, value)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    shipped = TEXTS[name]  # the lines before the value are the shipped ones
    line = shipped[: shipped.index(old) + new.index("{v}")].count("\n") + 1  # the value's line (its key's)
    assert message.startswith(f"{named}: {key} (line {line}): expected "), message
    assert "\n" not in message and len(message) < 600, message


# -- from the command line: one error: line, exit 2, no run directory ------------------------------
CLI_CASES = {
    "sigma_w 0 (divided by zero after the run directory existed)": (1, "0"),
    "size 0 (MuJoCo's traceback)": (0, "0"),
    "size 1e-300": (0, "1e-300"),
    "size 1e30": (0, "1e30"),
    "bounds -1e308 (params must be finite, after the run directory existed)": (31, "-1e308"),
    "bounds 1e308": (32, "1e308"),
}
SIGMA_SITE = next(s for s in SITES if s[3] == "rewards[0].constants.sigma_w")


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_train_refuses_before_writing(tmp_path, capsys, case):
    index, value = CLI_CASES[case]
    site = SIGMA_SITE if index == 1 else SITES[index]
    path, named, text = mutated(tmp_path, site, value)
    out = tmp_path / "out"
    code, stderr = invoke(capsys, "train", path, "--out", out, "--budget", "12", "--init", "6", "--batch-size", "6")
    error_line(code, stderr, "train", f"{named}: {site[3]} (line ")
    assert not out.exists()


def test_optimizer_options_are_bounded_on_the_command_line_and_in_a_run(tmp_path, capsys):
    out = tmp_path / "out"
    code, stderr = invoke(capsys, "train", "push", "--out", out, "--optimizer-option", "n_raw=99999999999")
    error_line(code, stderr, "train", "--optimizer-option: acquisition setting n_raw: must be at most 65536, got 99999999999")
    assert not out.exists()
    for name, maximum in MAXIMUM.items():  # every bound is a setting, and its maximum is a value
        assert name in NAMES
        setting_value(name, maximum)
        with pytest.raises(ValueError, match=f"acquisition setting {name}: must be at most"):
            setting_value(name, maximum * 2 + 1)


def test_a_run_that_stored_a_huge_option_names_its_config(tmp_path, capsys):
    from push_runs import push_run

    run = push_run(tmp_path / "run")
    config = run.path / "config.yaml"
    text = config.read_text()
    assert text.count("optimizer_options: {}") == 1
    config.write_text(text.replace("optimizer_options: {}", "optimizer_options: {n_raw: 99999999999}"))
    code, stderr = invoke(capsys, "train", "push", "--resume", run.path)
    error_line(code, stderr, "train", f"{config}: optimizer_options.n_raw (line ", "must be at most 65536")


def test_what_mujoco_refuses_names_the_entry(tmp_path):
    # each value inside its domain, together a body MuJoCo cannot give a positive definite inertia
    text = TEXTS["push"].replace("size: [0.15, 0.30, 0.07]\n    mass: 2.5", "size: [1e-4, 1e-4, 1e-4]\n    mass: 1e-6")
    path = tmp_path / "tiny.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=rf"^{re.escape(str(path))}: objects.ObjectToBePushed-1.mass "
                                            rf"\(line {line_of(text, 'mass: 1e-6')}\): MuJoCo cannot build"):
        load_scenario(path)


# -- bounded error text, no file content ---------------------------------------------------
# Where a long text lands in a scenario: (line as shipped, the line with {v}).
LONG_SITES = [
    ("name: push", "name: {v}"),
    ("mass: 2.5", "mass: {v}"),
    ("  ObjectToBePushed-1:\n    type: item", "  {v}:\n    type: item"),
    ("goal: (skiros:at skiros:ObjectToBePushed-1 skiros:ObjectGoalPose-1)", "goal: {v}"),
    ("kind: object_pose_divergence, objective: success, weight: 1.0,\n     object: ObjectToBePushed-1, target: "
     "ObjectGoalPose-1,\n     constants: {sigma_w: 0.4, d_o: 0.0, position_weight: 6.0",
     "kind: {v}, objective: success, weight: 1.0,\n     object: ObjectToBePushed-1, target: "
     "ObjectGoalPose-1,\n     constants: {sigma_w: 0.4, d_o: 0.0, position_weight: 6.0"),
    ("skill_library: ", "skill_library: {v} #"),
    ("scene: /", "scene: {v} #"),
    ("mjcf_body: object ", "mjcf_body: {v} "),
    ("position_tolerance: 0.01", "position_tolerance: {v}"),
]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(site=st.sampled_from(LONG_SITES), size=st.integers(300, 200_000),
       char=st.sampled_from(["x", "9", "é", "-"]))
def test_an_error_line_stays_short_however_long_the_value(tmp_path, capsys, site, size, char):
    old, new = site
    text = TEXTS["push"]
    assert old in text, old
    long_value = "a" + char * size + "!"  # a valid value nowhere (a name, a number, a path that exists)
    path = tmp_path / "long.yaml"
    path.write_text(text.replace(old, new.replace("{v}", long_value), 1))
    try:
        load_scenario(path)
    except UserError as err:
        message = str(err)
    else:
        pytest.fail("a scenario with a long value loaded")
    assert len(message) <= 1000 and long_value[:400] not in message, message[:300]  # a prefix at most
    code, stderr = invoke(capsys, "plan", path)
    line = error_line(code, stderr, "plan")
    assert len(line) <= MAX_MESSAGE_CHARS + 100


def test_a_one_scalar_document_is_not_shown(tmp_path, capsys):
    path = tmp_path / "huge.yaml"
    path.write_text("x" * 900_000)
    code, stderr = invoke(capsys, "plan", path)
    line = error_line(code, stderr, "plan", f"{path}: <top level> (line 1): expected a mapping, got text of 900000 characters")
    assert "xxxxxxxxxx" not in line and len(line) < 400


# Any printable text in a file that is not named YAML (never opened); in a *.yaml file, plain
# text (no YAML syntax): the document is one value, described, never shown.
ANY_TEXT = st.text(st.characters(min_codepoint=33, max_codepoint=126), min_size=12, max_size=80)
PLAIN_TEXT = st.text(st.sampled_from("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.;=+/"),
                     min_size=12, max_size=80)
SECRETS = st.one_of(st.tuples(ANY_TEXT, st.sampled_from(["", ".txt", ".conf", ".key", ".json"])),
                    st.tuples(PLAIN_TEXT, st.sampled_from([".yaml", ".yml"])))


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=SECRETS, lines=st.integers(1, 5))
def test_a_skill_library_of_another_kind_is_never_shown(tmp_path, capsys, case, lines):
    secret, suffix = case
    secret_file = tmp_path / f"passwd{suffix}"
    content = "\n".join(f"{secret}{i}" for i in range(lines)) + "\n"
    secret_file.write_text(content)
    text = TEXTS["push"].replace("skill_library: ", f"skill_library: {secret_file} #", 1)
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    code, stderr = invoke(capsys, "plan", path)
    if code == 0:  # a secret that happens to be YAML naming skills: nothing to show
        return
    line = error_line(code, stderr, "plan")
    for chunk in (secret[i:i + 12] for i in range(0, len(secret) - 11, 6)):
        if chunk not in str(secret_file) and chunk not in str(path):
            assert chunk not in stderr, (chunk, line)


def test_etc_passwd_as_skill_library_is_refused_unread(tmp_path, capsys):
    text = TEXTS["push"].replace("skill_library: ", "skill_library: /etc/passwd #", 1)
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    code, stderr = invoke(capsys, "plan", path)
    error_line(code, stderr, "plan", f"{path}: skill_library (line ", "'/etc/passwd' is not a YAML file")
    assert "root:" not in stderr
