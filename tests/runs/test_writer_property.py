"""The one writer (``mjxskill.runs.outputs.write_outputs``) and the commands that write
through it: a link planted at any depth below what a command owns
(a run's output folders, ``select``'s export, ``plan --export``, the explore page's cache) is
refused with one error naming it and the link's target is unchanged; a FIFO where a file is
read is refused, never waited on; a file or folder of the user's is replaced only with
``--replace``; and a write that fails or is killed with SIGKILL midway leaves the previous
state, no partial file, and a staging that the next write beside it removes."""

from mjxskill.evaluation.render import default_gl

default_gl()

import errno  # noqa: E402
import os  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import textwrap  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from cli_helpers import error_line, invoke, subprocess_env  # noqa: E402
from mjxskill.errors import RunError  # noqa: E402
from mjxskill.runs import atomic_write  # noqa: E402
from mjxskill.runs import outputs  # noqa: E402
from mjxskill.runs.atomic_write import STAGING, make_folder, read_below, write_json  # noqa: E402
from mjxskill.runs.outputs import write_outputs  # noqa: E402

USERS = b"a file of the user's\n"
FAST = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
SLOW = settings(max_examples=6, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def tree(folder: Path) -> dict:
    """Everything below ``folder``, no link followed: relative path -> bytes, ("link", target),
    "folder" or "fifo"."""
    out = {}
    for here, dirs, files in os.walk(folder):
        for name in dirs + files:
            path = Path(here, name)
            key = str(path.relative_to(folder))
            if path.is_symlink():
                out[key] = ("link", os.readlink(path))
            elif path.is_dir():
                out[key] = "folder"
            elif path.is_fifo():
                out[key] = "fifo"
            else:
                out[key] = path.read_bytes()
    return out


def stagings(folder: Path) -> list[str]:
    return sorted(str(p) for p in Path(folder).rglob("*") if STAGING.fullmatch(p.name))


@pytest.fixture
def outside(tmp_path):
    """A folder and a file of the user's outside every root: where planted links point."""
    folder = tmp_path / "outside"
    folder.mkdir()
    (folder / "keep.txt").write_bytes(USERS)
    return folder


def _plant(path: Path, kind: str, outside: Path) -> None:
    """A link at ``path``: to the user's folder, the user's file, or the folder above (``..``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    target = {"folder": outside, "file": outside / "keep.txt", "up": Path("..")}[kind]
    path.symlink_to(target)


# -- the writer: a link at every depth of an output --------------------------------------------
names = st.sampled_from(["selected-0", "frames", "explore", "evaluation-3", "known-0", "evaluation", "x"])


@FAST
@given(folders=st.lists(names, min_size=1, max_size=4), depth=st.integers(0, 4),
       kind=st.sampled_from(["folder", "file", "up"]), as_folder=st.booleans())
def test_a_link_at_any_depth_below_the_root_is_refused_and_its_target_unchanged(tmp_path_factory, folders, depth, kind,
                                                                                 as_folder):
    base = tmp_path_factory.mktemp("w")
    outside = base / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_bytes(USERS)
    root = base / "run"
    root.mkdir()
    (root / "config.yaml").write_bytes(b"a run's own file\n")
    target = root.joinpath(*folders, "out")
    content = {"frame_0000.png": b"png 0", "frame_0001.png": b"png 1"} if as_folder else b"text\n"
    chain = [root.joinpath(*folders[:i + 1]) for i in range(len(folders))] + [target]
    link = chain[min(depth, len(chain) - 1)]  # a folder on the way, or the output itself
    _plant(link, kind, outside)
    before_root, before_outside = tree(root), tree(outside)
    with pytest.raises(RunError, match=f"{link} is a symbolic link"):
        write_outputs(root, {target: content}, replace=True)
    assert tree(outside) == before_outside and tree(root) == before_root
    with pytest.raises(RunError, match=f"{link} is a symbolic link"):
        make_folder(root, target)
    if link != target:  # the files appended or replaced one at a time (evaluation/, run files) too
        with pytest.raises(RunError, match=f"{link} is a symbolic link"):
            write_json(target, {"a": 1}, root=root)
        with pytest.raises(RunError, match=f"{link} is a symbolic link"):
            atomic_write.append_text(target, "line\n", root=root)
    assert tree(outside) == before_outside and tree(root) == before_root


@FAST
@given(folders=st.lists(names, max_size=3), fifo_at=st.integers(0, 3))
def test_a_fifo_where_a_file_is_read_or_written_is_refused_never_waited_on(tmp_path_factory, folders, fifo_at):
    root = tmp_path_factory.mktemp("f")
    target = root.joinpath(*folders, "worlds.json")
    chain = [root.joinpath(*folders[:i + 1]) for i in range(len(folders))] + [target]
    fifo = chain[min(fifo_at, len(chain) - 1)]
    fifo.parent.mkdir(parents=True, exist_ok=True)
    os.mkfifo(fifo)
    before = tree(root)
    with pytest.raises(RunError, match=str(fifo)):
        read_below(root, target)
    with pytest.raises(RunError, match=str(fifo)):
        write_outputs(root, {target: b"{}\n"}, replace=True)
    assert tree(root) == before


def test_a_cached_document_behind_a_link_or_a_fifo_is_no_cache(tmp_path, outside):
    from mjxskill.explore.solutions import _write_json, read_cached

    run = tmp_path / "push-0"
    folder = run / "explore" / "evaluation-3"
    (outside / "worlds.json").write_text('{"format": "mjxskill.explore/1", "params": [1.0]}')
    _plant(run / "explore", "folder", outside)  # the cache folder itself linked elsewhere
    folder_link = run / "explore" / "evaluation-3" / "worlds.json"
    assert read_cached(folder_link, [1.0], run) is None
    with pytest.raises(RunError, match=f"{run / 'explore'} is a symbolic link"):
        _write_json(run, folder / "worlds.json", {"params": [2.0]})
    (run / "explore").unlink()
    folder.mkdir(parents=True)
    os.mkfifo(folder / "worlds.json")
    assert read_cached(folder / "worlds.json", [1.0], run) is None  # returns at once: a FIFO is never opened
    assert (outside / "worlds.json").read_text().endswith("[1.0]}")


# -- a folder swapped for a link between the check and the write (TOCTOU) ---------------------------
def _swap_for_link(folder: Path, outside: Path) -> None:
    """What a concurrent process does in the window: the real folder moved away, a link to the
    user's folder put in its place."""
    folder.rename(folder.with_name(folder.name + "-moved"))
    folder.symlink_to(outside)


def _with_file_of_the_users(folder: Path, name: str) -> None:
    (folder / name).write_bytes(USERS)


# every writer of a run's files that goes below the run, and what it does: path -> its call
SWAPPED_WRITERS = {
    "replace_whole": lambda target, root: atomic_write.replace_whole(target, lambda fh: fh.write(b"new\n"), root=root),
    "write_json": lambda target, root: write_json(target, {"a": 1}, root=root),
    "append_text": lambda target, root: atomic_write.append_text(target, "line\n", root=root),
    "remove_file": lambda target, root: atomic_write.remove_file(target, root=root),
    "keep_copy": lambda target, root: atomic_write.keep_copy(target, "kept.json"),
    "lock": lambda target, root: outputs_lock(target.parent),
}


def outputs_lock(folder: Path) -> None:
    from mjxskill.runs.run_lock import lock_run

    lock_run(folder).release()


@pytest.mark.parametrize("writer", SWAPPED_WRITERS)
@pytest.mark.parametrize("swapped", ["folder", "file"])
def test_a_link_swapped_in_after_the_check_is_never_followed(tmp_path, monkeypatch, outside, writer, swapped):
    """Between a writer's check of the folders and its write, a folder below the root (or the
    file itself) becomes a link to the user's folder: nothing there is written, replaced or
    removed. The swap is made at the first moment a writer can be interrupted after its check:
    right after ``open_folder`` (the check) returns, or, for a writer that holds its folder
    otherwise (the lock), right after that folder is opened."""
    root = tmp_path / "run"
    folder = root / "evaluation"
    folder.mkdir(parents=True)
    target = folder / "result.json"
    target.write_bytes(b"old\n")
    for name in ("result.json", "result.json.tmp", "kept.json", ".lock"):
        _with_file_of_the_users(outside, name)  # what a write through the link would change
    before = tree(outside)
    swaps = []

    def swap() -> None:
        if swaps:
            return
        swaps.append(True)
        if swapped == "folder":
            _swap_for_link(folder, outside)
        else:
            target.unlink()
            target.symlink_to(outside / "result.json")

    real_open_folder, real_open = atomic_write.open_folder, os.open

    def open_folder_then_swap(*args, **kwargs):
        fd = real_open_folder(*args, **kwargs)
        swap()
        return fd

    def open_then_swap(path, flags, *args, **kwargs):  # the lock opens its folder itself
        fd = real_open(path, flags, *args, **kwargs)
        if flags & os.O_DIRECTORY and Path(os.fsdecode(path)) == folder:
            swap()
        return fd

    monkeypatch.setattr(atomic_write, "open_folder", open_folder_then_swap)
    monkeypatch.setattr(os, "open", open_then_swap)
    try:
        SWAPPED_WRITERS[writer](target, root)
    except RunError as err:  # a writer may refuse what it finds: never with a traceback's OSError
        assert "symbolic link" in str(err), err
    monkeypatch.undo()
    assert swaps, "the writer never reached the window"
    assert tree(outside) == before


# -- nothing of the user's replaced without the flag -------------------------------------------
@FAST
@given(as_folder=st.booleans(), same=st.booleans())
def test_other_content_is_kept_unless_replace_and_the_same_content_is_harmless(tmp_path_factory, as_folder, same):
    root = tmp_path_factory.mktemp("r")
    target = root / "out" / ("frames" if as_folder else "domain.pddl")
    new = {"frame_0000.png": b"new"} if as_folder else b"new\n"
    old = new if same else ({"frame_0000.png": b"mine", "notes.txt": b"mine"} if as_folder else b"mine\n")
    write_outputs(root, {target: old})
    before = tree(root)
    if same:
        assert write_outputs(root, {target: new}) == [target] and tree(root) == before
        return
    with pytest.raises(RunError, match=f"{target} holds other .*; it is kept: move it away, or replace it with --replace"):
        write_outputs(root, {target: new}, hint="move it away", flag="--replace")
    assert tree(root) == before
    write_outputs(root, {target: new}, replace=True)
    assert (sorted(p.name for p in target.iterdir()) == ["frame_0000.png"] if as_folder
            else target.read_bytes() == b"new\n")
    assert stagings(root) == []


# -- a write that fails or is killed midway --------------------------------------------------------
@FAST
@given(files=st.integers(1, 6), fail_at=st.integers(0, 6), existing=st.booleans(),
       errno_=st.sampled_from([errno.ENOSPC, errno.EIO, errno.EACCES]), depth=st.integers(0, 3))
def test_a_write_failing_midway_leaves_the_previous_state(tmp_path_factory, monkeypatch, files, fail_at, existing, errno_,
                                                          depth):
    base = tmp_path_factory.mktemp("k")
    root = base.joinpath(*["nested"] * depth)  # a root the user named whose folders are not there yet
    params = root / "selected-0" / "parameters.yaml"
    frames = root / "selected-0" / "frames"
    if existing:
        write_outputs(root, {params: b"old\n", frames: {f"frame_{i:04d}.png": b"old" for i in range(3)}})
    before = tree(base)
    new = {params: b"new\n", frames: {f"frame_{i:04d}.png": b"new %d" % i for i in range(files)}}
    write_file, calls = outputs._write_file, []

    def failing(fd, name, data):
        calls.append(name)
        if len(calls) > fail_at:
            raise OSError(errno_, os.strerror(errno_))
        return write_file(fd, name, data)

    monkeypatch.setattr(outputs, "_write_file", failing)
    if fail_at >= 1 + files:  # every file written before the failure point: the new export, whole
        write_outputs(root, new, replace=True)
        monkeypatch.undo()
        assert tree(root)[str(params.relative_to(root))] == b"new\n" and stagings(root) == []
        return
    with pytest.raises((OSError, RunError)) as raised:
        write_outputs(root, new, replace=True)
    monkeypatch.undo()
    if errno_ == errno.EACCES:  # not the disk's fault: a RunError naming the path (exit 2)
        assert isinstance(raised.value, RunError) and "cannot write" in str(raised.value)
    else:  # the machine's fault: raised as it is (exit 1)
        assert isinstance(raised.value, OSError)
    after = tree(base)
    assert stagings(base) == []
    if not existing:  # nothing of a new export stays, the folders made for it included
        assert after == before
    else:  # each output old or new, whole
        assert after[str(params.relative_to(base))] in (b"old\n", b"new\n")
        at = str(frames.relative_to(base)) + "/"
        kept = {k: v for k, v in after.items() if k.startswith(at)}
        assert kept in ({k: v for k, v in before.items() if k.startswith(at)},
                        {f"{at}{n}": d for n, d in new[frames].items()})


KILLED_WHILE_WRITING = textwrap.dedent("""
    import os, signal, sys
    from pathlib import Path
    from mjxskill.runs import outputs

    root, kill_at = Path(sys.argv[1]), int(sys.argv[2])
    write_file, calls = outputs._write_file, []

    def killed(fd, name, data):
        calls.append(name)
        if len(calls) > kill_at:
            os.kill(os.getpid(), signal.SIGKILL)
        return write_file(fd, name, data)

    outputs._write_file = killed
    frames = {f"frame_{i:04d}.png": b"new %d" % i for i in range(5)}
    outputs.write_outputs(root, {root / "selected-0" / "parameters.yaml": b"new\\n",
                                      root / "selected-0" / "frames": frames}, replace=True)
""")


@SLOW
@given(kill_at=st.integers(0, 6))
def test_a_write_killed_with_sigkill_leaves_the_previous_state_and_a_rerun_finishes(tmp_path_factory, kill_at):
    root = tmp_path_factory.mktemp("s")
    old = {root / "selected-0" / "parameters.yaml": b"old\n",
           root / "selected-0" / "frames": {f"frame_{i:04d}.png": b"old" for i in range(3)}}
    write_outputs(root, old)
    before = tree(root)
    done = subprocess.run([sys.executable, "-c", KILLED_WHILE_WRITING, str(root), str(kill_at)], capture_output=True,
                          text=True, env=subprocess_env(), timeout=120)
    after = {k: v for k, v in tree(root).items() if not any(STAGING.fullmatch(part) for part in Path(k).parts)}
    if done.returncode == 0:  # got through before the kill point: the new export, whole
        assert after["selected-0/parameters.yaml"] == b"new\n"
    else:
        assert done.returncode == -signal.SIGKILL, done.stderr
        assert after["selected-0/parameters.yaml"] in (b"old\n", b"new\n")
        frames = {k: v for k, v in after.items() if k.startswith("selected-0/frames/")}
        assert frames in ({k: v for k, v in before.items() if k.startswith("selected-0/frames/")},
                          {f"selected-0/frames/frame_{i:04d}.png": b"new %d" % i for i in range(5)})
        assert not any(v == b"" for v in frames.values())  # no 0-byte frame
    # the rerun: the new export, and no staging of the killed process left
    new = {root / "selected-0" / "parameters.yaml": b"new\n",
           root / "selected-0" / "frames": {f"frame_{i:04d}.png": b"new %d" % i for i in range(5)}}
    write_outputs(root, new, replace=True)
    assert stagings(root) == []
    assert tree(root) == {"selected-0": "folder", "selected-0/parameters.yaml": b"new\n", "selected-0/frames": "folder",
                          **{f"selected-0/frames/frame_{i:04d}.png": b"new %d" % i for i in range(5)}}


# -- the commands ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def push_run(tmp_path_factory):
    from explore_runs import make_push_run

    return make_push_run(tmp_path_factory.mktemp("runs") / "push-0")


EXPORT_DEPTHS = ["selected-0", "selected-0/parameters.yaml", "selected-0/parameters.json", "selected-0/frames"]


@SLOW
@given(at=st.sampled_from(EXPORT_DEPTHS), kind=st.sampled_from(["folder", "file", "up"]), out=st.booleans())
def test_select_refuses_a_link_at_any_depth_of_its_export(push_run, tmp_path_factory, capsys, at, kind, out):
    base = tmp_path_factory.mktemp("sel")
    outside = base / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_bytes(USERS)
    root = base / "mine" if out else push_run.path
    # --out names the export folder itself: the user's to choose (a link there is followed); below it, never
    relative = ("frames" if at == "selected-0" else at.removeprefix("selected-0/")) if out else at
    link = root / relative
    _plant(link, kind, outside)
    before_run, before_outside = tree(push_run.path), tree(outside)
    try:
        args = ["--pick", 0, "--size", 32, 24] + (["--out", root] if out else [])
        # a link where the frames go is refused before anything is rendered; else --no-render
        code, err = invoke(capsys, "select", push_run.path, *args, *([] if link.name == "frames" else ["--no-render"]))
        error_line(code, err, "select", str(link), "is a symbolic link")
        assert tree(push_run.path) == before_run and tree(outside) == before_outside
    finally:
        link.unlink()
        if link.parent != root:  # the folder made to hold the link: empty, nothing was written into it
            link.parent.rmdir()


def test_select_out_keeps_the_users_frames_and_replaces_them_only_with_replace(push_run, tmp_path, capsys):
    mine = tmp_path / "mine"
    (mine / "frames").mkdir(parents=True)
    (mine / "frames" / "frame_0000.png").write_bytes(USERS)
    code, err = invoke(capsys, "select", push_run.path, "--pick", 0, "--size", 32, 24, "--out", mine)
    if code == 1 and "rendering skipped" in err:
        from capabilities import no_render

        no_render(err)
    error_line(code, err, "select", str(mine / "frames"), "holds other files", "--replace")
    assert tree(mine) == {"frames": "folder", "frames/frame_0000.png": USERS}  # nor the parameters: nothing written
    code, err = invoke(capsys, "select", push_run.path, "--pick", 0, "--size", 32, 24, "--out", mine, "--replace")
    assert code == 0, err
    frames = sorted((mine / "frames").iterdir())
    assert frames and all(p.read_bytes().startswith(b"\x89PNG") for p in frames)
    assert sorted(p.name for p in mine.iterdir()) == ["frames", "parameters.json", "parameters.yaml"]
    assert stagings(mine) == []


def test_select_checks_its_inputs_before_the_first_write(push_run, tmp_path, capsys):
    out = tmp_path / "export"
    code, err = invoke(capsys, "select", push_run.path, "--pick", 0, "--config-index", 99, "--out", out)
    error_line(code, err, "select", "--config-index 99")
    assert not out.exists()


@SLOW
@given(at=st.sampled_from(["domain.pddl", "problem.pddl"]), kind=st.sampled_from(["file", "folder", "up", "users"]))
def test_plan_export_refuses_a_link_or_a_users_file_and_writes_neither(tmp_path_factory, capsys, at, kind):
    base = tmp_path_factory.mktemp("plan")
    outside = base / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_bytes(USERS)
    folder = base / "pddl"
    if kind == "users":
        folder.mkdir()
        (folder / at).write_bytes(USERS)
    else:
        _plant(folder / at, kind, outside)
    before, before_outside = tree(folder), tree(outside)
    code, err = invoke(capsys, "plan", "push", "--export", folder)
    line = error_line(code, err, "plan", str(folder / at), "it is kept")
    assert ("--replace" in line) == (kind == "users")  # a link is never replaced, a file of the user's only with it
    assert tree(folder) == before and tree(outside) == before_outside
    if kind == "users":
        assert invoke(capsys, "plan", "push", "--export", folder, "--replace")[0] == 0
        assert (folder / at).read_bytes().startswith(b"(define")
        assert invoke(capsys, "plan", "push", "--export", folder)[0] == 0  # the same again: harmless


@pytest.mark.parametrize("command", ["select", "train"])
def test_a_repetition_linked_to_another_inside_the_run_is_refused(tmp_path, capsys, command):
    """``seed-1 -> seed-0`` stays inside the run, so a check of the run's top level alone lets it be; writing seed-1's
    files would write seed-0's."""
    import shutil

    from explore_runs import make_repeated_run

    root = make_repeated_run(tmp_path / "push-x3")
    shutil.rmtree(root.path / "seed-1")
    (root.path / "seed-1").symlink_to("seed-0")
    unlocked = lambda: {k: v for k, v in tree(root.path).items() if k != ".lock"}  # noqa: E731  (the lock says who wrote last)
    before = unlocked()
    code, err = invoke(capsys, command, *(["push", "--resume"] if command == "train" else []), root.path)
    error_line(code, err, command, str(root.path / "seed-1"), "is a symbolic link")
    assert unlocked() == before


def test_an_export_path_the_system_cannot_open_is_one_error_exit_2(push_run, tmp_path, capsys):
    """A loop of links or a name too long for the file system as select's --out: refused before
    anything is written, as bad input (exit 2), not as a fault of the machine."""
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    code, err = invoke(capsys, "select", push_run.path, "--pick", 0, "--no-render", "--out", loop / "inside")
    error_line(code, err, "select", str(loop))
    long = tmp_path / ("x" * 300)
    code, err = invoke(capsys, "select", push_run.path, "--pick", 0, "--no-render", "--out", long)
    error_line(code, err, "select", "x" * 40)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop"]
