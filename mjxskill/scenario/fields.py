"""Reading a YAML file as data with every error naming the file, the key path and the line.

``yaml.compose`` (safe, no tags executed) gives the node tree with start marks; a ``Field`` is
one node plus its key path, and its accessors check types and report errors like
``push.yaml: objects.Peg-1.mass (line 12): expected a number, got 'heavy'``.
"""

from __future__ import annotations

import math
from pathlib import Path

import yaml

from mjxskill.errors import ScenarioError

_constructor = yaml.constructor.SafeConstructor()


def compose_file(path: Path) -> "Field":
    """The document in ``path`` as a root Field. Raises ScenarioError for unreadable YAML."""
    source = str(path)
    try:
        text = Path(path).read_text()
    except OSError as err:
        raise ScenarioError(f"{source}: cannot read the scenario file ({err.strerror})") from None
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(err, "problem", None) or str(err)
        raise ScenarioError(f"{source}{line}: not valid YAML: {problem}") from None
    if node is None:
        raise ScenarioError(f"{source}: the file is empty")
    return Field(node, "", source)


class Field:
    """One YAML node with its key path (e.g. ``robot.start_configs[2]``) and source file."""

    def __init__(self, node: yaml.Node, path: str, source: str, key_node: yaml.Node | None = None):
        self.node = node
        self.path = path
        self.source = source
        self.key_node = key_node  # for a mapping entry: errors point at its key's line

    @property
    def line(self) -> int:
        return (self.key_node or self.node).start_mark.line + 1

    # -- errors -------------------------------------------------------------------------------
    def where(self) -> str:
        return f"{self.source}: {self.path or '<top level>'} (line {self.line})"

    def fail(self, message: str):
        raise ScenarioError(f"{self.where()}: {message}")

    def _child_path(self, key) -> str:
        if isinstance(key, int):
            return f"{self.path}[{key}]"
        return f"{self.path}.{key}" if self.path else str(key)

    # -- containers ---------------------------------------------------------------------------
    def items(self) -> list[tuple[str, "Field"]]:
        """Key/value pairs of a mapping with string keys, in file order; duplicates rejected."""
        if not isinstance(self.node, yaml.MappingNode):
            self.fail(f"expected a mapping, got {self._describe()}")
        seen: dict[str, int] = {}
        pairs = []
        for key_node, value_node in self.node.value:
            key = Field(key_node, self.path, self.source).scalar()
            if not isinstance(key, str):
                Field(key_node, self._child_path(key), self.source).fail(f"keys must be names, got {key!r}")
            if key in seen:
                Field(key_node, self._child_path(key), self.source).fail(
                    f"duplicate key {key!r} (first on line {seen[key]})"
                )
            seen[key] = key_node.start_mark.line + 1
            pairs.append((key, Field(value_node, self._child_path(key), self.source, key_node)))
        return pairs

    def mapping(self, required: tuple[str, ...] = (), optional: tuple[str, ...] = ()) -> dict[str, "Field"]:
        """The mapping's fields; every ``required`` key present, no key outside both lists."""
        fields = dict(self.items())
        allowed = set(required) | set(optional)
        for key, field in fields.items():
            if key not in allowed:
                field.fail(f"unknown key {key!r}; expected one of {sorted(allowed)}")
        for key in required:
            if key not in fields:
                self.fail(f"missing key {key!r}")
        return fields

    def seq(self) -> list["Field"]:
        if not isinstance(self.node, yaml.SequenceNode):
            self.fail(f"expected a list, got {self._describe()}")
        return [Field(n, self._child_path(i), self.source) for i, n in enumerate(self.node.value)]

    # -- scalars ------------------------------------------------------------------------------
    def scalar(self):
        if not isinstance(self.node, yaml.ScalarNode):
            self.fail(f"expected a single value, got {self._describe()}")
        return _constructor.construct_object(self.node)

    def is_null(self) -> bool:
        return isinstance(self.node, yaml.ScalarNode) and self.node.tag.endswith(":null")

    def string(self, choices=None) -> str:
        value = self.scalar()
        if not isinstance(value, str) or not value:
            self.fail(f"expected a name (text), got {value!r}")
        if choices is not None and value not in choices:
            self.fail(f"{value!r} is not one of {sorted(choices)}")
        return value

    def boolean(self) -> bool:
        value = self.scalar()
        if not isinstance(value, bool):
            self.fail(f"expected true or false, got {value!r}")
        return value

    def number(self, positive: bool = False, nonnegative: bool = False) -> float:
        value = self.scalar()
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(f"expected a number, got {value!r}")
        if positive and value <= 0:
            self.fail(f"expected a positive number, got {value!r}")
        if nonnegative and value < 0:
            self.fail(f"expected a number >= 0, got {value!r}")
        return float(value)

    def integer(self, minimum: int | None = None) -> int:
        value = self.scalar()
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"expected an integer, got {value!r}")
        if minimum is not None and value < minimum:
            self.fail(f"expected an integer >= {minimum}, got {value!r}")
        return value

    def vector(self, length: int | None = None) -> tuple[float, ...]:
        items = self.seq()
        if length is not None and len(items) != length:
            self.fail(f"expected a list of {length} numbers, got {len(items)}")
        return tuple(item.number() for item in items)

    def matrix(self, columns: int) -> tuple[tuple[float, ...], ...]:
        return tuple(row.vector(columns) for row in self.seq())

    def strings(self) -> tuple[str, ...]:
        return tuple(item.string() for item in self.seq())

    def _describe(self) -> str:
        if isinstance(self.node, yaml.MappingNode):
            return "a mapping"
        if isinstance(self.node, yaml.SequenceNode):
            return "a list"
        return repr(_constructor.construct_object(self.node))
