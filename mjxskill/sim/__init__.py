"""MJX scenes, Cartesian impedance controller and motion generator for the 7-DOF iiwa.

Modules: ``scene`` (where the shipped assets are, MJCF loading, names), ``controller`` (JAX
impedance law, one control step), ``native_controller`` (the same law in numpy over native
MuJoCo: reference and baseline), ``motion`` (trapezoid point-to-point trajectories, Archimedes
spiral, ramps), ``batching`` (stepping W worlds at once), ``postures`` (start configurations,
inverse kinematics).
"""

from mjxskill.sim.scene import SCENES, asset_path, load_scene, scene_path

__all__ = ["SCENES", "asset_path", "load_scene", "scene_path"]
