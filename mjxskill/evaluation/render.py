"""Render one parameter set's episode with MuJoCo's offscreen renderer (PNG frames or MP4).

The episode is traced by the rollout's engine (``trace``: joint and object positions and the
mocap bodies at every BT tick, 10 Hz) and replayed into the native ``MjModel`` for drawing, so
each frame shows the world as that world had it: the object where the world started it, the
goal and its fixture (mocap bodies) where the world put them. MuJoCo needs an OpenGL backend
chosen *before* ``mujoco`` is imported: ``MUJOCO_GL=egl`` (headless GPU or Mesa's EGL),
``osmesa`` (software) or ``glfw`` (a display). ``python -m mjxskill.select`` defaults to egl
(``default_gl``, from ``mjxskill._headless``: importing this module imports no mujoco).
"""

from __future__ import annotations

import io
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from mjxskill._headless import default_gl, pyplot  # noqa: F401  (default_gl: callers import it from here too)
from mjxskill.errors import UserError, quote
from mjxskill.runs.outputs import write_outputs

if TYPE_CHECKING:  # pragma: no cover
    from mjxskill.engine.protocol import Rollout

GL_HELP = (
    "MuJoCo's offscreen renderer found no OpenGL backend (MUJOCO_GL={gl}: {err}). "
    "Headless Linux: install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri) and run with MUJOCO_GL=egl, "
    "or software OSMesa (apt-get install libosmesa6) with MUJOCO_GL=osmesa; with a display, MUJOCO_GL=glfw."
)
AFTER_SELECT = "The parameters were exported; pass --no-render to skip rendering."


class RenderUnavailable(UserError):
    """No OpenGL backend (or no video encoder) for rendering. ``reason``: what is missing and how
    to get it; the message adds ``next_step``, what the command can do about it."""

    def __init__(self, reason: str, next_step: str = ""):
        super().__init__(f"{reason} {next_step}" if next_step else reason)
        self.reason = reason


def _camera(model, data):
    # lazy: mujoco reads MUJOCO_GL once, when imported; default_gl() (mjxskill._headless) must
    # come first, and select and explore import this module before they call it
    import mujoco

    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    cam.lookat[:] = (0.5, 0.0, 0.15)  # the work area in front of the arm base
    cam.distance = 1.6
    cam.azimuth = 150.0
    cam.elevation = -30.0
    return cam


# (frames done, frames in all) after each drawn frame
FrameProgress = Callable[[int, int], None]


def frames(model, qpos: np.ndarray, width: int = 640, height: int = 480, progress: FrameProgress | None = None, *,
           mocap_pos: np.ndarray | None = None, mocap_quat: np.ndarray | None = None) -> np.ndarray:
    """(T, height, width, 3) uint8 images of the native ``model`` at each row of qpos (T, nq),
    with the mocap bodies at mocap_pos (T, M, 3) and mocap_quat (T, M, 4) (None: the model's)."""
    import mujoco  # lazy: after default_gl(), as in _camera

    data = mujoco.MjData(model)
    # the offscreen framebuffer is the model's visual/global offwidth x offheight (640 x 480 unless
    # the MJCF says more): as large as the frames for the context's creation, the model unchanged after
    frame = model.vis.global_
    kept = (frame.offwidth, frame.offheight)
    frame.offwidth, frame.offheight = max(kept[0], width), max(kept[1], height)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as err:  # the GL backends raise a variety of errors when no context exists
        raise RenderUnavailable(GL_HELP.format(gl=quote(os.environ.get("MUJOCO_GL", "")), err=f"{type(err).__name__}: {err}"),
                                AFTER_SELECT) from None
    finally:
        frame.offwidth, frame.offheight = kept
    images = []
    try:
        cam = None
        for t, q in enumerate(np.asarray(qpos, np.float64)):
            data.qpos[:] = q
            if mocap_pos is not None:
                data.mocap_pos[:] = mocap_pos[t]
            if mocap_quat is not None:
                data.mocap_quat[:] = mocap_quat[t]
            mujoco.mj_forward(model, data)
            cam = cam or _camera(model, data)
            renderer.update_scene(data, camera=cam)
            images.append(renderer.render().copy())
            if progress:
                progress(len(images), len(qpos))
    finally:
        renderer.close()
    return np.stack(images)


def png_frames(images: np.ndarray) -> dict[str, bytes]:
    """The frames as PNG files (``frame_0000.png`` -> its bytes), for the writer to put in place."""
    plt = pyplot()
    files = {}
    for t, image in enumerate(images):
        buffer = io.BytesIO()
        plt.imsave(buffer, image, format="png")
        files[f"frame_{t:04d}.png"] = buffer.getvalue()
    return files


def mp4_bytes(images: np.ndarray, fps: float) -> bytes:
    """The frames encoded by ffmpeg (through matplotlib's writer) into an MP4, in a private
    temporary folder: the writer puts the bytes in place."""
    if shutil.which("ffmpeg") is None:
        raise RenderUnavailable("MP4 needs ffmpeg on the PATH (apt-get install ffmpeg); use --format png for PNG frames")
    plt = pyplot()
    from matplotlib.animation import FFMpegWriter  # lazy: after pyplot() chose the backend, as pyplot

    h, w = images.shape[1:3]
    fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
    ax = fig.add_axes([0, 0, 1, 1])  # type: ignore[call-overload]  # matplotlib's stubs want a tuple; a list is one too
    ax.axis("off")
    shown = ax.imshow(images[0])
    writer = FFMpegWriter(fps=fps)  # type: ignore[arg-type]  # ffmpeg takes a fractional frame rate
    try:
        with tempfile.TemporaryDirectory(prefix="mjxskill-mp4-") as folder:
            path = Path(folder) / "episode.mp4"
            with writer.saving(fig, str(path), dpi=100):
                for image in images:
                    shown.set_data(image)
                    writer.grab_frame()
            return path.read_bytes()
    finally:
        plt.close(fig)


def rendered_path(out: Path, fmt: str) -> Path:
    """Where an episode rendered as ``fmt`` to ``out`` goes: ``out/`` (PNG frames) or ``out.mp4``."""
    return out.with_suffix(".mp4") if fmt == "mp4" else out


def render_world(rollout: Rollout, config_index: int, seed: int = 0):
    """The one world an episode is rendered in: start configuration ``config_index`` (a known
    one) with the objects randomized from ``seed`` (unbatched fields)."""
    import jax  # lazy: ~1 s; only a render needs it, and select's --help and --no-render do not

    worlds = rollout.worlds_per_config(jax.random.PRNGKey(seed), 1)
    return jax.tree.map(lambda x: x[config_index], worlds)


def render_content(rollout: Rollout, params: np.ndarray, world, fmt: str = "png", width: int = 640, height: int = 480,
                   progress: FrameProgress | None = None):
    """Traces ``params`` (P,) in ``world`` (one unbatched world; either engine's rollout) and
    draws it, the world's randomized poses shown: the PNG frames (name -> bytes) or the MP4's
    bytes, nothing written yet (``mjxskill.runs.outputs.write_outputs`` puts them in place
    whole, at ``rendered_path``)."""
    _, record = rollout.trace(params, world)
    images = frames(rollout.mj_model, np.asarray(record.qpos), width, height, progress,
                    mocap_pos=np.asarray(record.mocap_pos), mocap_quat=np.asarray(record.mocap_quat))
    if fmt == "mp4":
        return mp4_bytes(images, fps=rollout.scenario.bt_hz)
    return png_frames(images)


def rendered_files(out: Path, content) -> list[Path]:
    """The files of ``content`` (``render_content``) written to ``out`` (``rendered_path``)."""
    return [out] if isinstance(content, bytes) else [out / name for name in content]


def render_episode(rollout: Rollout, params: np.ndarray, world, out: Path, fmt: str = "png", width: int = 640, height: int = 480,
                   progress: FrameProgress | None = None, *, root: Path | None = None, replace: bool = True) -> list[Path]:
    """``render_content`` written into ``out/`` (PNG frames) or ``out.mp4``, staged beside it and
    renamed into place whole, never through a link below ``root`` (default: ``out``'s folder);
    an earlier rendering there is replaced only with ``replace``. Returns the written files."""
    content = render_content(rollout, params, world, fmt, width, height, progress)
    target = rendered_path(Path(out), fmt)
    write_outputs(Path(out).parent if root is None else root, {target: content}, replace=replace)
    return rendered_files(target, content)
