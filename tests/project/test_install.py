"""``pip install .`` gives a working mjxskill: a wheel built from the checkout carries
the scenarios, the skill library and the MJCF scenes (the package ``mjxskill.assets``, mapped
onto the checkout's ``assets/`` by pyproject.toml), and installed in a fresh venv it plans push,
peg and slide and trains a tiny push run from a directory outside the checkout.

The build is pip's, isolated: it takes setuptools from the package index. The venv sees the
packages of the interpreter running the tests (``--system-site-packages``, and a ``.pth`` file
naming that interpreter's site-packages: where the tests run in a virtual environment, its
packages are not the base interpreter's; no dependency is installed again) and gets the wheel
with ``--no-deps``; the tests check that its mjxskill is the wheel's, not the
checkout (an editable install of which the machine may also have). The wheel is built from a
copy of the checkout's build inputs, so that the build leaves no ``build/`` or ``*.egg-info`` in
the checkout. About 20 s on 2 cores, most of it the training run and the build.
"""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD_INPUTS = ("pyproject.toml", "README.md", "mjxskill", "assets")
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc")
TASKS = ("push", "peg", "peg_square", "slide")


def _run(cmd, cwd, timeout=300, env=None) -> subprocess.CompletedProcess:
    run = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)
    assert run.returncode == 0, f"{' '.join(map(str, cmd))}\n{run.stdout}\n{run.stderr}"
    return run


def _files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"}


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    """A copy of what the build reads: pyproject.toml, the README, the package and the assets."""
    src = tmp_path_factory.mktemp("source")
    for name in BUILD_INPUTS:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=IGNORED)
        else:
            shutil.copy2(path, src / name)
    return src


@pytest.fixture(scope="module")
def wheel(source, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--wheel-dir", out, "."], cwd=source)
    (built,) = out.glob("mjxskill-*.whl")
    return built


@pytest.fixture(scope="module")
def venv_python(wheel, tmp_path_factory) -> Path:
    """A fresh venv over the machine's packages with the wheel installed in it."""
    venv = tmp_path_factory.mktemp("venv")
    _run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", venv], cwd=venv)
    python = venv / "bin" / "python"
    # the running interpreter's packages: a venv's own, which --system-site-packages (the base
    # interpreter's) does not show; after the new venv's own, so the wheel's mjxskill comes first
    purelib = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=venv).stdout.strip())
    purelib.mkdir(parents=True, exist_ok=True)
    (purelib / "running-interpreter.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    # pip from the machine's packages, installing into the venv; --ignore-installed: the machine's
    # own mjxskill (outside the venv) is neither uninstalled nor taken for this one
    _run([python, "-m", "pip", "install", "--no-deps", "--ignore-installed", "--no-index", wheel], cwd=venv)
    return python


@pytest.fixture(scope="module")
def outside(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("outside")


def _env(outside: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # nothing of the checkout on sys.path
    env["MJXSKILL_CACHE_DIR"] = str(outside / "cache")
    return env


def test_pyproject_lists_every_package_of_the_checkout():
    # packages.find cannot see the mapped mjxskill.assets, so pyproject.toml lists the packages
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "mjxskill").rglob("__init__.py")}
    assert set(config["packages"]) == found | {"mjxskill.assets"}
    assert config["package-dir"] == {"mjxskill.assets": "assets"}
    assert (ROOT / "assets" / "__init__.py").is_file()


def test_the_wheel_holds_every_module_and_asset(source, wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    package = {f"mjxskill/{f}" for f in _files(source / "mjxskill")}
    assets = {f"mjxskill/assets/{f}" for f in _files(source / "assets")}
    assert package <= names, sorted(package - names)
    assert {n for n in names if n.startswith("mjxskill/assets/")} == assets
    assert "mjxskill/assets/scenarios/push.yaml" in assets and "mjxskill/assets/tools/pusher.xml" in assets
    assert all(n.startswith("mjxskill-") for n in names - package - assets), sorted(names - package - assets)


def test_the_installed_wheel_plans_and_trains_outside_the_checkout(venv_python, outside):
    env = _env(outside)
    site = venv_python.parents[1]
    run_dir = outside / "run"
    train = subprocess.Popen(
        [str(venv_python), "-m", "mjxskill.train", "push", "--budget", "8", "--batch-size", "6", "--init", "6",
         "--worlds", "1", "--episode-seconds", "0.5", "--engine", "native", "--quiet", "--out", str(run_dir)],
        cwd=outside, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # the venv's mjxskill is the wheel's, and so are its assets; a user's own copy of a scenario
        # elsewhere finds its scene and skill library relative to itself, as before
        check = _run([venv_python, "-c", CHECK, outside / "mine"], cwd=outside, env=env).stdout.split()
        assert check[0] == str(site / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}"
                               / "site-packages" / "mjxskill" / "__init__.py"), check
        assets = Path(check[1])
        assert assets == Path(check[0]).parent / "assets" and check[2] == ",".join(sorted(TASKS)), check
        mine = (outside / "mine").resolve()
        assert check[3:] == [str(mine / "push.xml"), str(mine / "skills" / "library.yaml")], check
        for task in TASKS:
            out = _run([venv_python, "-m", "mjxskill.plan", task], cwd=outside, env=env).stdout
            assert out.splitlines()[0] == f"task: {task} ({assets / 'scenarios' / f'{task}.yaml'})", out
            assert "plan:" in out and "1. GoToLinear" in out, out
        stdout, stderr = train.communicate(timeout=300)
    finally:
        if train.poll() is None:
            train.kill()
            train.wait()
    assert train.returncode == 0, f"{stdout}\n{stderr}"
    # the header and 6 evaluations: the robust protocol's 3/4 of the budget (its race has the rest)
    assert (run_dir / "evaluations.csv").read_text().count("\n") == 7
    assert "Traceback" not in stderr


def test_a_checkout_without_an_editable_install_reads_its_own_assets(venv_python, outside):
    # python -m in a checkout's root imports the checkout's mjxskill, not the installed wheel's:
    # then its assets are the checkout's assets/ too (README's first command after pip install .)
    out = _run([venv_python, "-c", "import mjxskill\nfrom mjxskill.sim import asset_path\n"
                "print(mjxskill.__file__, asset_path())"], cwd=ROOT, env=_env(outside)).stdout.split()
    assert out == [str(ROOT / "mjxskill" / "__init__.py"), str(ROOT / "assets")]


CHECK = """
import shutil, sys
from pathlib import Path
import mjxskill
from mjxskill.scenario import available_scenarios, load_scenario
from mjxskill.sim import asset_path
mine = Path(sys.argv[1])
shutil.copytree(asset_path(), mine)  # scenarios/push.yaml names ../push.xml and ../skills/library.yaml
scn = load_scenario(mine / "scenarios" / "push.yaml")
print(mjxskill.__file__, asset_path(), ",".join(available_scenarios()), scn.scene, *scn.libraries)
"""
