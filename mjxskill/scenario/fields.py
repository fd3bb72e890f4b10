"""Reading a YAML file as data with every error naming the file, the key path and the line.

``yaml.compose`` (safe, no tags executed) gives the node tree with start marks; a ``Field`` is
one node plus its key path, and its accessors check types and report errors like
``push.yaml: objects.Peg-1.mass (line 12): expected a number, got 'heavy'``.

What is read is bounded before anything is built from it: files over ``MAX_BYTES`` are refused
(a 20 MB scenario took 144 s and 1.8 GB to compose), the text must be UTF-8, only the plain
YAML tags are accepted (``!kg`` or ``!!python/...`` name no value we know), and aliases may not
expand the document beyond ``MAX_NODES`` nodes (a 1 KB "billion laughs" document is harmless
as a node graph but explodes wherever it is walked or printed), and lists and mappings may nest
at most ``MAX_DEPTH`` deep (composing is recursive: a 47 KB scenario nested 20,000 deep was a
RecursionError in every command; the check counts while composing, so it is refused at the
first node too deep, with its line). The error class is the
caller's: ``ScenarioError`` for scenarios, ``RunError`` for a run's ``config.yaml``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NoReturn

import yaml

from mjxskill._files import read_regular
from mjxskill.errors import ScenarioError, UserError, quote
from mjxskill.scenario.domain import Domain

_constructor = yaml.constructor.SafeConstructor()

MAX_BYTES = 1 << 20  # the shipped scenarios are about 10 KB
MAX_NODES = 100_000  # nodes after alias expansion; the shipped scenarios have about 2,000
MAX_DEPTH = 64  # lists and mappings inside one another; the shipped scenarios nest 7 deep
# A key names something (an object, a skill, a parameter) that reaches PDDL, CSV headers, plots
# and error lines; the shipped scenarios' longest is 31 characters.
MAX_KEY_CHARS = 100
# A text value (a goal, a description, a tree's line); the shipped scenarios' longest is 200.
MAX_TEXT_CHARS = 10_000
# A PDDL symbol: a letter, then letters, digits, - or _ (ASCII: what every PDDL parser reads).
PDDL_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")
_STANDARD = "tag:yaml.org,2002:"
# What the safe loader resolves plain values to, plus the two collections.
ALLOWED_TAGS = frozenset(_STANDARD + t for t in ("null", "bool", "int", "float", "str", "timestamp", "seq", "map"))


def read_text(path: Path, error: type[UserError] = ScenarioError, what: str = "scenario file") -> str:
    """The UTF-8 text of ``path``, at most ``MAX_BYTES`` long; ``error`` names the problem."""
    source = str(path)
    try:
        data = read_regular(path, MAX_BYTES)  # a regular file only (a FIFO would block), bounded even if it grows
    except OSError as err:
        raise error(f"{source}: cannot read the {what} ({err.strerror})") from None
    if len(data) > MAX_BYTES:
        raise error(f"{source}: the {what} is larger than {MAX_BYTES // 1024} KiB; refusing to read it")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
        raise error(f"{source} (line {line}, column {column}): byte 0x{data[err.start]:02x} is not UTF-8 text") from None


def compose_file(path: Path, error: type[UserError] = ScenarioError, what: str = "scenario file") -> "Field":
    """The document in ``path`` as a root Field. Raises ``error`` for unreadable YAML."""
    return compose_text(read_text(path, error, what), str(path), error)


class _TooDeep(Exception):
    def __init__(self, mark):
        super().__init__()
        self.mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """The safe loader's composer, refusing collections nested deeper than MAX_DEPTH."""

    _depth = 0

    def compose_node(self, parent, index):
        if not self.check_event(yaml.SequenceStartEvent, yaml.MappingStartEvent):
            return super().compose_node(parent, index)  # a value or an alias: no deeper
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _TooDeep(self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def compose_text(text: str, source: str, error: type[UserError] = ScenarioError) -> "Field":
    """The YAML document ``text`` (read from ``source``) as a root Field, checked for tags,
    nesting and alias expansion; raises ``error`` naming ``source`` and the line."""
    try:
        node = yaml.compose(text, Loader=_BoundedLoader)
    except _TooDeep as err:
        raise error(f"{source} (line {err.mark.line + 1}, column {err.mark.column + 1}): lists and mappings nest more "
                    f"than {MAX_DEPTH} deep; refusing the document") from None
    except yaml.YAMLError as err:
        raise error(f"{source}{_mark(err, text)}: not valid YAML: {_problem(err)}") from None
    if node is None:
        raise error(f"{source}: the file is empty")
    _check_nodes(node, source, error)
    return Field(node, "", source, error=error)


def _mark(err: yaml.YAMLError, text: str) -> str:
    mark = getattr(err, "problem_mark", None)
    if mark is not None:
        return f" (line {mark.line + 1}, column {mark.column + 1})"
    position = getattr(err, "position", None)  # a ReaderError (a control character) has no mark
    if isinstance(position, int):
        return f" (line {text.count(chr(10), 0, position) + 1})"
    return ""


def _problem(err: yaml.YAMLError) -> str:
    if isinstance(err, yaml.reader.ReaderError):  # str(err) would name "<unicode string>"
        code = err.character if isinstance(err.character, int) else ord(err.character)
        return f"the character #x{code:04x} is not allowed in YAML ({err.reason})"
    return _one_line(getattr(err, "problem", None) or err)[:200]  # a token of the text at most


KEY_CHARS = 40  # a key in a key path (``objects.<key>.mass``) is cut to this many characters


def _key_text(key) -> str:
    """A mapping key as it appears in a key path, at most KEY_CHARS characters."""
    text = str(key)
    return text if len(text) <= KEY_CHARS else text[: KEY_CHARS - 3] + "..."


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _check_nodes(root: yaml.Node, source: str, error: type[UserError]) -> None:
    """Refuses unknown tags and documents whose aliases expand beyond MAX_NODES nodes; the
    error names the key path and line like ``Field.where``.

    Sizes are counted once per distinct node (aliases share nodes), so this is linear in the
    text even for a document built to explode."""
    size: dict[int, int] = {}
    active: set[int] = set()

    def fail(node: yaml.Node, path: str, message: str):
        raise error(f"{source}: {path or '<top level>'} (line {node.start_mark.line + 1}): {message}")

    # Iterative post-order walk: a deep document must not hit Python's recursion limit.
    stack: list[tuple[yaml.Node, str, bool]] = [(root, "", False)]
    while stack:
        node, path, done = stack.pop()
        key = id(node)
        if done:
            active.discard(key)
            size[key] = 1 + sum(size[id(child)] for child, _ in _children(node, path))
            if size[key] > MAX_NODES:
                fail(node, path, f"expands to more than {MAX_NODES} values (YAML aliases *name repeat what they "
                                 "point to); refusing the document")
            continue
        if key in size:
            continue
        if key in active:
            fail(node, path, "an alias refers to the list or mapping it is in")
        if node.tag not in ALLOWED_TAGS:
            tag = "!!" + node.tag[len(_STANDARD):] if node.tag.startswith(_STANDARD) else node.tag
            fail(node, path, f"the YAML tag {tag} is not supported: write plain numbers, text, true/false, lists and mappings")
        active.add(key)
        stack.append((node, path, True))
        stack.extend((child, child_path, False) for child, child_path in _children(node, path) if id(child) not in size)


def _children(node: yaml.Node, path: str) -> list[tuple[yaml.Node, str]]:
    """The child nodes of a collection with their key paths (a mapping's keys too)."""
    if isinstance(node, yaml.MappingNode):
        out = []
        for key, value in node.value:
            name = _key_text(key.value) if isinstance(key, yaml.ScalarNode) else "?"
            child = f"{path}.{name}" if path else str(name)
            out += [(key, child), (value, child)]
        return out
    if isinstance(node, yaml.SequenceNode):
        return [(child, f"{path}[{i}]") for i, child in enumerate(node.value)]
    return []


class Field:
    """One YAML node with its key path (e.g. ``robot.start_configs[2]``) and source file."""

    def __init__(self, node: yaml.Node, path: str, source: str, key_node: yaml.Node | None = None,
                 error: type[UserError] = ScenarioError):
        self.node = node
        self.path = path
        self.source = source
        self.key_node = key_node  # for a mapping entry: errors point at its key's line
        self.error = error

    @property
    def line(self) -> int:
        return (self.key_node or self.node).start_mark.line + 1

    # -- errors -------------------------------------------------------------------------------
    def where(self) -> str:
        return f"{self.source}: {self.path or '<top level>'} (line {self.line})"

    def fail(self, message: str) -> NoReturn:
        raise self.error(f"{self.where()}: {message}")

    def _child(self, node: yaml.Node, path: str, key_node: yaml.Node | None = None) -> "Field":
        return Field(node, path, self.source, key_node, self.error)

    def _child_path(self, key) -> str:
        if isinstance(key, int):
            return f"{self.path}[{key}]"
        key = _key_text(key)
        return f"{self.path}.{key}" if self.path else key

    # -- containers ---------------------------------------------------------------------------
    def items(self) -> list[tuple[str, "Field"]]:
        """Key/value pairs of a mapping with string keys, in file order; duplicates rejected."""
        if not isinstance(self.node, yaml.MappingNode):
            self.fail(f"expected a mapping, got {self._describe()}")
        seen: dict[str, int] = {}
        pairs = []
        for key_node, value_node in self.node.value:
            key = self._child(key_node, self.path).scalar()
            if not isinstance(key, str):
                self._child(key_node, self._child_path(str(key))).fail(f"keys must be names, got {quote(key)}")
            if len(key) > MAX_KEY_CHARS:
                self._child(key_node, self.path).fail(
                    f"a key of {len(key)} characters ({quote(key)}); keys name things, at most {MAX_KEY_CHARS}"
                )
            if key in seen:
                self._child(key_node, self._child_path(key)).fail(
                    f"duplicate key {quote(key)} (first on line {seen[key]})"
                )
            seen[key] = key_node.start_mark.line + 1
            pairs.append((key, self._child(value_node, self._child_path(key), key_node)))
        return pairs

    def mapping(self, required: tuple[str, ...] = (), optional: tuple[str, ...] = ()) -> dict[str, "Field"]:
        """The mapping's fields; every ``required`` key present, no key outside both lists."""
        fields = dict(self.items())
        allowed = set(required) | set(optional)
        for key, field in fields.items():
            if key not in allowed:
                field.fail(f"unknown key {quote(key)}; expected one of {sorted(allowed)}")
        for key in required:
            if key not in fields:
                self.fail(f"missing key {key!r}")
        return fields

    def seq(self) -> list["Field"]:
        if not isinstance(self.node, yaml.SequenceNode):
            self.fail(f"expected a list, got {self._describe()}")
        return [self._child(n, self._child_path(i)) for i, n in enumerate(self.node.value)]

    # -- scalars ------------------------------------------------------------------------------
    def scalar(self):
        if not isinstance(self.node, yaml.ScalarNode):
            self.fail(f"expected a single value, got {self._describe()}")
        try:
            return _constructor.construct_object(self.node)
        except Exception as err:  # noqa: BLE001  (e.g. !!float abc, !!bool maybe: any failure is a bad value)
            self.fail(f"cannot read {quote(self.node.value)} as {self.node.tag.rpartition(':')[2]}: "
                      f"{_one_line(err)[:200]}")

    def is_null(self) -> bool:
        return isinstance(self.node, yaml.ScalarNode) and self.node.tag.endswith(":null")

    def string(self, choices=None) -> str:
        value = self.scalar()
        if not isinstance(value, str) or not value:
            self.fail(f"expected a name (text), got {quote(value)}")
        if len(value) > MAX_TEXT_CHARS:
            self.fail(f"a text of {len(value)} characters ({quote(value)}); at most {MAX_TEXT_CHARS}")
        if choices is not None and value not in choices:
            self.fail(f"{quote(value)} is not one of {sorted(choices)}")
        return value

    def pddl_name(self, name: str | None = None, what: str = "name") -> str:
        """``name`` (this field's string without one) checked as a PDDL symbol of at most
        ``MAX_KEY_CHARS`` characters: scenario, type, object and skill names become PDDL symbols."""
        text = self.string() if name is None else name
        if len(text) > MAX_KEY_CHARS or not PDDL_NAME.fullmatch(text):
            self.fail(f"{quote(text)} is not usable as {what}: a letter, then letters, digits, - or _ "
                      f"(ASCII, at most {MAX_KEY_CHARS} characters)")
        return text

    def boolean(self) -> bool:
        value = self.scalar()
        if not isinstance(value, bool):
            self.fail(f"expected true or false, got {quote(value)}")
        return value

    def number(self, domain: Domain | None = None, *, positive: bool = False, nonnegative: bool = False,
               maximum: float | None = None) -> float:
        """The value as a float inside ``domain`` (``mjxskill.scenario.domain``; without one: finite,
        and > 0 with ``positive``, >= 0 with ``nonnegative``, <= ``maximum``)."""
        if domain is None:
            domain = Domain(minimum=0.0 if positive or nonnegative else None, maximum=maximum, exclusive_minimum=positive)
        value = self.scalar()
        if isinstance(value, str) and self.node.style is None:
            try:  # YAML 1.1 reads an exponent without a dot (1e300, 5e-3) as text; it means a number
                value = float(value)
            except ValueError:
                pass
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(f"expected a number, got {quote(value)}")
        problem = domain.problem(value)
        if problem:
            self.fail(problem)
        return float(value)

    def integer(self, minimum: int | None = None, maximum: int | None = None) -> int:
        value = self.scalar()
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"expected an integer, got {quote(value)}")
        if minimum is not None and value < minimum:
            self.fail(f"expected an integer >= {minimum}, got {quote(value)}")
        if maximum is not None and value > maximum:
            self.fail(f"expected an integer <= {maximum}, got {quote(value)}")
        return value

    def vector(self, length: int | None = None, domain: Domain | None = None) -> tuple[float, ...]:
        """A list of numbers (``length`` of them when given), each inside ``domain``."""
        items = self.seq()
        if length is not None and len(items) != length:
            self.fail(f"expected a list of {length} numbers, got {len(items)}")
        return tuple(item.number(domain) for item in items)

    def matrix(self, columns: int, domain: Domain | None = None) -> tuple[tuple[float, ...], ...]:
        return tuple(row.vector(columns, domain) for row in self.seq())

    def strings(self) -> tuple[str, ...]:
        return tuple(item.string() for item in self.seq())

    def _describe(self) -> str:
        if isinstance(self.node, yaml.MappingNode):
            return "a mapping"
        if isinstance(self.node, yaml.SequenceNode):
            return "a list"
        if not self.path:  # the whole document is one value: a file of another kind; never show it
            return (f"text of {len(self.node.value)} characters, not YAML keys and values (is {self.source} "
                    "the file meant?)")
        return quote(self.scalar())
