"""Extended behavior trees: node model, reference interpreter, and plan-to-tree expansion."""

from mjxskill.ebt.interpreter import Interpreter, TickResult, run_script
from mjxskill.ebt.nodes import Kind, Node, Status, render

__all__ = ["Interpreter", "Kind", "Node", "Status", "TickResult", "render", "run_script"]
