"""What a key path of the problem file takes as one value, read from the schema's models.

``cpopt sweep --vary KEY=SPEC`` parses the values of SPEC by it, so that ``0.1,abc`` for a
number, ``1:3:3`` for a choice or ``optimize,1`` are refused as the user wrote them, before
any point is made.
"""

from __future__ import annotations

import types
import typing
from dataclasses import dataclass

from pydantic import BaseModel

from ..io.keypath import parse_key_path
from .schema import ProblemSpec

NUMBER, BOOLEAN, WORD = "number", "boolean", "word"
"""The kinds of one value of a key: a finite number, true or false, a word (a choice or
text)."""


@dataclass(frozen=True)
class KeyType:
    """The kinds of value a key takes.

    Attributes
    ----------
    kinds : frozenset of str
        Some of :data:`NUMBER`, :data:`BOOLEAN` and :data:`WORD`.
    words : tuple of str
        The allowed words of a choice; empty when any text is allowed (or no word at all).
    """

    kinds: frozenset[str]
    words: tuple[str, ...] = ()

    def describe(self) -> str:
        """What the key takes, in words: ``a number``, ``true or false``, ``one of a, b``."""
        parts = []
        if NUMBER in self.kinds:
            parts.append("a finite number")
        if BOOLEAN in self.kinds:
            parts.append("true or false")
        if WORD in self.kinds:
            parts.append(f"one of {', '.join(self.words)}" if self.words else "text")
        return " or ".join(parts)


def _options(annotation) -> list:
    """The members of a type annotation: through ``Annotated`` and unions, without None."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _options(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return [o for arg in typing.get_args(annotation) for o in _options(arg)]
    return [] if annotation is type(None) else [annotation]


def _step(annotation, part: str | int) -> list:
    """The annotations one key (a name or a list index) leads to from ``annotation``."""
    origin = typing.get_origin(annotation)
    if isinstance(part, str) and isinstance(annotation, type):
        if issubclass(annotation, BaseModel) and part in annotation.model_fields:
            return _options(annotation.model_fields[part].annotation)
        return []
    if isinstance(part, str) and origin is dict:
        return _options(typing.get_args(annotation)[1])
    if isinstance(part, int) and origin is list:
        return _options(typing.get_args(annotation)[0])
    return []


def _leaf(annotation) -> tuple[set[str], tuple[str, ...]]:
    """The kinds and allowed words of one member annotation (none for a mapping or list)."""
    if typing.get_origin(annotation) is typing.Literal:
        return {WORD}, tuple(str(w) for w in typing.get_args(annotation))
    if annotation is bool:
        return {BOOLEAN}, ()
    if annotation in (int, float):
        return {NUMBER}, ()
    if annotation is str:
        return {WORD}, ()
    return set(), ()


def key_type(path: str) -> KeyType | None:
    """What the key at ``path`` (``optimizer.curve``, ``arm.links[2].mass``) takes as one
    value; None when the schema has no such key or it holds a mapping or a list only
    (validation then says what is wrong with the value).

    Raises
    ------
    KeyPathError
        For a malformed key path.
    """
    members = [ProblemSpec]
    for part in parse_key_path(path):
        members = [found for member in members for found in _step(member, part)]
    kinds: set[str] = set()
    words: list[str] = []
    text = False
    for member in members:
        found, allowed = _leaf(member)
        kinds |= found
        words += allowed
        text = text or (WORD in found and not allowed)
    if not kinds:
        return None
    return KeyType(frozenset(kinds), () if text else tuple(dict.fromkeys(words)))


__all__ = ["BOOLEAN", "NUMBER", "WORD", "KeyType", "key_type"]
