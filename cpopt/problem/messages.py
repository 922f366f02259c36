"""Pydantic's validation errors in the user's words: the key path, what was expected, a
suggestion for a misspelt key; and keys that older files may still have."""

from __future__ import annotations

import difflib
import re
import typing

from pydantic import BaseModel

from ..io.safe_yaml import echo, key_path
from .schema import UNION_TAGS, ProblemError, ProblemSpec


def _model_in(annotation) -> type[BaseModel] | None:
    """The first pydantic model inside a type annotation (through lists, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


REMOVED_KEYS = {
    ("optimizer", "solver", "jit"): (
        "this key was removed: the optimizer's per-sample functions are now always compiled to "
        "C once per arm kind and cached in the user's cache folder (no setting needed; see "
        "'Compiled samples' in docs/problems.md); delete the key"
    ),
}
"""Keys that older files may have, with what replaced them."""


def check_removed_keys(data: dict, source: str) -> None:
    """Refuse a key of :data:`REMOVED_KEYS` in problem data, saying what replaced it."""
    for path, why in REMOVED_KEYS.items():
        node = data
        for key in path[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if isinstance(node, dict) and path[-1] in node:
            raise ProblemError(source, ".".join(path), why)


def _allowed_keys(loc) -> list[str]:
    model: type[BaseModel] | None = ProblemSpec
    for part in loc[:-1]:
        if model is None or isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return []
        model = _model_in(field.annotation)
    return list(model.model_fields) if model else []


FREE_NAME = re.compile(r"(start|goal|via\[\d+\])\.\w+")
"""A free value's name (``via[0].xi_after``): a key of ``optimizer.free``, not a type tag."""


def _user_keys(loc: tuple) -> tuple:
    """The parts of a pydantic error location that are the user's keys and indices: type tags
    (``list[...]``) and the tags of the control points' union (after an index) are dropped."""
    keys = []
    for part in loc:
        tag = isinstance(part, str) and (
            ("[" in part and not FREE_NAME.fullmatch(part))
            or (part in UNION_TAGS and keys and isinstance(keys[-1], int))
        )
        if not tag:
            keys.append(part)
    return tuple(keys)


def describe_error(error: dict) -> tuple[str, str]:
    """The key path and message of one pydantic error (``ValidationError.errors()`` item)."""
    loc = _user_keys(error["loc"])
    path = key_path(loc)
    kind = error["type"]
    given = error.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc)
        return (
            path,
            f"unknown key{suggestion(str(loc[-1]), allowed)} (allowed here: {', '.join(allowed)})",
        )
    if kind == "missing":
        return path, "required key is missing"
    msg = error["msg"]
    msg = msg[0].lower() + msg[1:]
    return path, f"{msg}, got {echo(given)}"


def suggestion(given: str, allowed: list[str]) -> str:
    """``; did you mean 'theta_deg'?``: a name that only lacks its unit first, then the closest."""
    low = given.lower()
    for name in allowed:
        if low in (name.lower(), name.lower().removesuffix("_deg")):
            return f"; did you mean '{name}'?"
    close = difflib.get_close_matches(given, allowed, n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def interval(lo: float | None, hi: float | None) -> str:
    """``[lo, hi]`` with a missing bound as -inf or inf."""
    return f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
