"""Where the shipped assets live (scenarios, skill library, MJCF scenes), how to load a scene
(host side, native MuJoCo) and the names every scene gives the arm."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import mujoco

# The shipped assets are the package mjxskill.assets: pyproject.toml maps it onto the checkout's
# top-level assets/, so a wheel carries them inside mjxskill/ and an editable install reads the
# checkout's folder.
ASSETS_PACKAGE = "mjxskill.assets"
SCENES = ("push", "peg", "peg_square")

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
TOOL_SITE = "tool"


def asset_path(*parts: str) -> Path:
    """Path of a shipped asset, e.g. ``asset_path("scenarios", "push.yaml")``; ``asset_path()``
    is the assets folder (it may not exist).

    Found through ``importlib.resources``: inside the installed package for ``pip install .``,
    the checkout's ``assets/`` for ``pip install -e .``. mjxskill imported from a source tree
    it was not installed from (``python -m`` in a checkout's root, ``PYTHONPATH``) has no
    ``mjxskill.assets``: the tree's own ``assets/`` serve then.
    """
    try:
        root = files(ASSETS_PACKAGE)
    except ModuleNotFoundError as err:
        if err.name != ASSETS_PACKAGE:
            raise
        root = Path(__file__).resolve().parents[2] / "assets"
        if not (root / "__init__.py").is_file():
            raise ModuleNotFoundError(
                f"mjxskill's assets ({ASSETS_PACKAGE}) are not installed and {Path(__file__).resolve().parents[1]} "
                f"has no assets/ beside it: reinstall mjxskill (pip install . or, from a checkout, pip install -e .)",
                name=ASSETS_PACKAGE,
            ) from None
    if not isinstance(root, Path):  # a zip import: MuJoCo and the scenario loader read files
        raise RuntimeError(f"mjxskill's assets must be files on disk, not {root!r}: install mjxskill unzipped")
    return root.joinpath(*parts)


def scene_path(name: str) -> Path:
    """Path of the shipped scene ``<name>.xml``; ``name`` is one of :data:`SCENES`."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; expected one of {SCENES}")
    return asset_path(f"{name}.xml")


def load_scene(name: str) -> mujoco.MjModel:
    """Native MjModel of the shipped scene ``name`` (one of SCENES), as its MJCF file has it."""
    return mujoco.MjModel.from_xml_path(str(scene_path(name)))
