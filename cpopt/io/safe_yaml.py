"""Reading a YAML file someone else wrote: bounded in size, nesting and aliases, strict on keys.

A problem file is small (a few kB). What is read here may be anything: a device, a FIFO, a
huge file, an alias bomb, keys written twice. :func:`read_yaml` reads only regular files of at
most :data:`MAX_BYTES`, composes the document with limits on nesting (:data:`MAX_DEPTH`),
aliases (:data:`MAX_ALIASES`) and expanded size (:data:`MAX_NODES`), refuses duplicate keys
with their key path, and reads ``1e-8`` and ``1e9`` as numbers (YAML 1.1 reads them as strings
because they lack a dot). Every refusal is a :class:`YamlInputError` with a key path; values
echoed in messages are cut by :func:`echo`.
"""

from __future__ import annotations

import os
import re
import reprlib
import stat
from pathlib import Path

import yaml
from yaml.events import (
    AliasEvent,
    MappingEndEvent,
    SequenceEndEvent,
    StreamEndEvent,
)
from yaml.nodes import MappingNode, ScalarNode, SequenceNode

MAX_BYTES = 1_000_000
"""Largest problem file read [bytes] (1 MB; real ones are a few kB)."""
MAX_DEPTH = 20
"""Deepest nesting of mappings and lists (a problem file needs 5)."""
MAX_ALIASES = 100
"""Most aliases (``*name``) in one document."""
MAX_NODES = 100_000
"""Most values in the document with every alias expanded (an alias bomb has billions)."""
MAX_ECHO = 80
"""Longest echo of a value in a message [characters]."""

_MERGE = "tag:yaml.org,2002:merge"
_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlist = _REPR.maxdict = _REPR.maxtuple = 6
_REPR.maxlevel = 2


class YamlInputError(ValueError):
    """A YAML file that cannot be read, with the key path at fault (``""`` for the file)."""

    def __init__(self, path: str, message: str) -> None:
        self.path, self.message = path, message
        super().__init__(f"{path}: {message}" if path else message)


def echo(value, limit: int = MAX_ECHO) -> str:
    """A short repr of a value for a message: at most ``limit`` characters."""
    return cut(_REPR.repr(value), limit)


def cut(text: str, limit: int = MAX_ECHO) -> str:
    """Text for a message, cut to at most ``limit`` characters."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def key_path(parts) -> str:
    """``motion.via[0].t`` from ``("motion", "via", 0, "t")``; long keys are cut."""
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            name = str(part)
            name = name if len(name) <= 40 else name[:37] + "..."
            out += ("." if out else "") + name
    return out


class _Resolver(yaml.resolver.Resolver):
    """YAML 1.1 plus floats without a dot (``1e-8``, ``1e9``, ``-2E+3``), as in YAML 1.2."""


_Resolver.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


class _LimitedComposer(yaml.composer.Composer):
    """PyYAML's composer with limits, duplicate-key refusal and key paths in its errors."""

    def __init__(self) -> None:
        super().__init__()
        self._path: list = []
        self._aliases = 0
        self._size = 0
        self._weight: dict[int, int] = {}

    def _fail(self, message: str, mark=None) -> None:
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise YamlInputError(key_path(self._path), message + where)

    def compose_node(self, parent, index):
        if len(self._path) > MAX_DEPTH:
            self._fail(f"nested deeper than {MAX_DEPTH} levels", self.peek_event().start_mark)
        if self.check_event(AliasEvent):
            event = self.get_event()
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                self._fail(f"more than {MAX_ALIASES} aliases in one file", event.start_mark)
            if event.anchor not in self.anchors:  # also an alias to its own enclosing node
                self._fail(f"alias *{echo(event.anchor)} names no complete anchor before it")
            node = self.anchors[event.anchor]
            self._count(self._weight[id(node)], event.start_mark)
            return node
        event = self.peek_event()
        anchor = event.anchor
        if anchor is not None and anchor in self.anchors:
            self._fail(f"anchor &{echo(anchor)} defined twice", event.start_mark)
        before = self._size
        node = super().compose_node(parent, index)
        self._weight[id(node)] = self._size - before
        return node

    def _count(self, weight: int, mark) -> None:
        self._size += weight
        if self._size > MAX_NODES:
            self._fail(f"more than {MAX_NODES} values with aliases expanded", mark)

    def compose_scalar_node(self, anchor):
        self._count(1, self.peek_event().start_mark)
        return super().compose_scalar_node(anchor)

    def compose_sequence_node(self, anchor):
        start = self.get_event()
        self._count(1, start.start_mark)
        node = SequenceNode(
            self._tag(SequenceNode, start), [], start.start_mark, None, flow_style=start.flow_style
        )
        while not self.check_event(SequenceEndEvent):
            self._path.append(len(node.value))
            node.value.append(self.compose_node(node, len(node.value)))
            self._path.pop()
        node.end_mark = self.get_event().end_mark
        self._anchor(anchor, node)
        return node

    def compose_mapping_node(self, anchor):
        start = self.get_event()
        self._count(1, start.start_mark)
        node = MappingNode(
            self._tag(MappingNode, start), [], start.start_mark, None, flow_style=start.flow_style
        )
        seen: dict = {}
        while not self.check_event(MappingEndEvent):
            key = self.compose_node(node, None)
            name = key.value if isinstance(key, ScalarNode) else "?"
            self._path.append(name)
            if isinstance(key, ScalarNode) and key.tag != _MERGE:
                if (key.tag, key.value) in seen:
                    first = seen[key.tag, key.value]
                    line = key.start_mark.line
                    self._fail(f"duplicate key at line {line + 1} (first at line {first + 1})")
                seen[key.tag, key.value] = key.start_mark.line
            node.value.append((key, self.compose_node(node, key)))
            self._path.pop()
        node.end_mark = self.get_event().end_mark
        self._anchor(anchor, node)
        return node

    def _tag(self, kind, event) -> str:
        tag = event.tag
        return self.resolve(kind, None, event.implicit) if tag is None or tag == "!" else tag

    def _anchor(self, anchor, node) -> None:
        # registered once complete, so an alias inside its own node is refused, not recursive
        if anchor is not None:
            self.anchors[anchor] = node


try:  # libyaml's C parser: a 1 MB file in milliseconds instead of seconds
    from yaml.cyaml import CParser

    _PARSING: tuple = (CParser,)
except ImportError:  # PyYAML without libyaml
    _PARSING = (yaml.reader.Reader, yaml.scanner.Scanner, yaml.parser.Parser)


class _Loader(_LimitedComposer, *_PARSING, yaml.constructor.SafeConstructor, _Resolver):
    def __init__(self, text: str) -> None:
        if len(_PARSING) == 1:
            _PARSING[0].__init__(self, text)
        else:
            for base in _PARSING:
                base.__init__(self, *([text] if base is yaml.reader.Reader else []))
        _LimitedComposer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        _Resolver.__init__(self)


def parse_yaml(text: str):
    """Parse one YAML document with the limits of this module.

    The limits and their messages are cpopt's whatever the PyYAML version: when PyYAML stops
    first (6.0.4 refuses nesting past 1000 levels while it scans ahead, before any node reaches
    this module's composer), the text it accepted is composed again, and a limit of this
    module found there is reported with its key path instead of PyYAML's words.

    Raises
    ------
    YamlInputError
        For malformed YAML, a limit exceeded or a duplicate key (with its key path).
    """
    try:
        return _parse(text)
    except _MalformedError as err:
        if err.index:
            try:
                _parse(text[: err.index])
            except YamlInputError as first:
                if not isinstance(first, _MalformedError):
                    raise first from None
        raise YamlInputError(err.path, err.message) from None


class _MalformedError(YamlInputError):
    """PyYAML's own refusal, with the index in the text where it stopped (0 if unknown)."""

    def __init__(self, message: str, index: int = 0) -> None:
        super().__init__("", message)
        self.index = index


def _parse(text: str):
    loader = _Loader(text)
    try:
        loader.get_event()  # stream start
        node = None
        if not loader.check_event(StreamEndEvent):
            node = loader.compose_document()
        if not loader.check_event(StreamEndEvent):
            raise YamlInputError("", "expected one YAML document, found more")
        return None if node is None else loader.construct_document(node)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        message = f"malformed YAML{where}: {cut(err.problem or '')}"
        raise _MalformedError(message, mark.index if mark else 0) from None
    except (yaml.YAMLError, ValueError, OverflowError) as err:
        if isinstance(err, YamlInputError):
            raise
        raise _MalformedError(f"malformed YAML: {cut(str(err))}") from None
    finally:
        loader.dispose()


def read_text(path: str | Path) -> str:
    """The UTF-8 text of a regular file of at most :data:`MAX_BYTES`.

    Opens without blocking (a FIFO with no writer does not hang) and checks what was opened,
    so a device, FIFO, socket or directory is refused before anything is read.

    Raises
    ------
    YamlInputError
        With an empty key path.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise YamlInputError("", "no such file") from None
    except (OSError, ValueError) as err:
        raise YamlInputError("", f"cannot read the file ({cut(str(err))})") from None
    try:
        data = _read_regular(fd)
    finally:
        os.close(fd)
    if len(data) > MAX_BYTES:
        raise YamlInputError("", _too_big(len(data)))
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise YamlInputError("", f"not UTF-8 text (byte {err.start} cannot be decoded)") from None


def _read_regular(fd: int) -> bytes:
    mode = os.fstat(fd)
    if stat.S_ISDIR(mode.st_mode):
        raise YamlInputError("", "is a directory, expected a YAML problem file")
    if not stat.S_ISREG(mode.st_mode):
        raise YamlInputError(
            "", "is not a regular file (a device, FIFO or socket); cpopt reads files only"
        )
    if mode.st_size > MAX_BYTES:
        raise YamlInputError("", _too_big(mode.st_size))
    chunks, size = [], 0
    try:
        while size <= MAX_BYTES:
            chunk = os.read(fd, MAX_BYTES + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as err:
        raise YamlInputError("", f"cannot read the file ({cut(str(err))})") from None
    return b"".join(chunks)


def _too_big(size: int) -> str:
    return f"is larger than {MAX_BYTES} bytes (1 MB), the limit for problem files"


def read_yaml(path: str | Path):
    """Read and parse a YAML file with every limit of this module (see the module docstring)."""
    return parse_yaml(read_text(path))


__all__ = ["MAX_BYTES", "YamlInputError", "cut", "echo", "key_path", "parse_yaml", "read_yaml"]
