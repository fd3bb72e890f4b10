"""The simulated robot and its world, host side (native MuJoCo; nothing here imports MJX).

Modules: ``scene`` (where the shipped assets are, MJCF loading, the names every scene gives the
arm), ``model`` (a scenario's MJCF scene with the world model's physics written in, with
``mujoco.MjSpec``), ``shapes`` (each world-model shape's inertia and geoms), ``controller_config``
(the impedance controller's static settings, shared by both engines), ``tool_force`` (the
measured interaction force), ``postures`` and ``inverse_kinematics`` (the start configurations).
The controller and motion generator themselves are per engine: ``mjxskill.engine.mjx`` and
``mjxskill.engine.native``.
"""

from mjxskill.sim.scene import SCENES, asset_path, load_scene, scene_path

__all__ = ["SCENES", "asset_path", "load_scene", "scene_path"]
