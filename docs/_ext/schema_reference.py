"""Sphinx directive ``cpopt-schema``: the problem-file reference, made from the pydantic schema.

The tables are built at documentation build time from :class:`cpopt.problem.schema.ProblemSpec`
(its JSON schema: types, bounds, defaults, and each block's docstring), so the reference cannot
drift from what :func:`cpopt.load` accepts.
"""

from __future__ import annotations

import json
import re

from docutils import nodes
from docutils.parsers.rst import Directive

LITERAL = re.compile(r"``(.+?)``")


def _text(parent: nodes.Element, text: str) -> nodes.Element:
    """Append ``text`` to ``parent``, with ``double backticks`` as literals."""
    pos = 0
    for match in LITERAL.finditer(text):
        if match.start() > pos:
            parent += nodes.Text(text[pos : match.start()])
        parent += nodes.literal(match.group(1), match.group(1))
        pos = match.end()
    if pos < len(text):
        parent += nodes.Text(text[pos:])
    return parent


def _bounds(schema: dict) -> str:
    marks = [  # JSON schema's words, and pydantic's own behind a before-validator
        ("exclusiveMinimum", "> {}"),
        ("gt", "> {}"),
        ("minimum", ">= {}"),
        ("ge", ">= {}"),
        ("exclusiveMaximum", "< {}"),
        ("lt", "< {}"),
        ("maximum", "<= {}"),
        ("le", "<= {}"),
    ]
    found = [form.format(schema[key]) for key, form in marks if key in schema]
    return f" ({', '.join(found)})" if found else ""


def describe(schema: dict) -> str:
    """A type in words: ``number (> 0)``, ``pair of number``, ``one of "a", "b"``."""
    if "$ref" in schema:
        return f"block {schema['$ref'].rsplit('/', 1)[-1]} (below)"
    if "anyOf" in schema:
        return " or ".join(describe(s) for s in schema["anyOf"])
    if "const" in schema:
        return json.dumps(schema["const"])
    if "enum" in schema:
        return "one of " + ", ".join(json.dumps(v) for v in schema["enum"])
    kind = schema.get("type")
    if kind == "number":
        return "number" + _bounds(schema)
    if kind == "integer":
        return "whole number" + _bounds(schema)
    if kind == "boolean":
        return "true or false"
    if kind == "string":
        return "text"
    if kind == "null":
        return "null"
    if kind == "array":
        item = describe(schema.get("items", {}))
        low, high = schema.get("minItems"), schema.get("maxItems")
        if low == high == 2:
            return f"pair of ({item})"
        if low == high == 3:
            return f"triple of ({item})"
        if low is not None and low == high:
            return f"list of {low} ({item})"
        size = f", at least {low}" if low else ""
        return f"list of ({item}){size}"
    if kind == "object":
        extra = schema.get("additionalProperties")
        if isinstance(extra, dict):
            return f"mapping of name to ({describe(extra)})"
        return "mapping"
    return "any value"


def _refs(schema: dict) -> list[tuple[str, bool]]:
    """The blocks a field's value may be: (definition name, as a list item)."""
    found = []
    if "$ref" in schema:
        found.append((schema["$ref"].rsplit("/", 1)[-1], False))
    for sub in schema.get("anyOf", []):
        found.extend(_refs(sub))
    if schema.get("type") == "array" and "items" in schema:
        found.extend((name, True) for name, _ in _refs(schema["items"]))
    return found


def _table(rows: list[tuple[str, str, str]]) -> nodes.table:
    table = nodes.table(classes=["cpopt-schema"])
    group = nodes.tgroup(cols=3)
    table += group
    for width in (22, 50, 28):
        group += nodes.colspec(colwidth=width)
    head = nodes.thead()
    group += head
    body = nodes.tbody()
    group += body
    for target, cells in ((head, [("key", "type", "default")]), (body, rows)):
        for cells_row in cells:
            row = nodes.row()
            for i, cell in enumerate(cells_row):
                entry = nodes.entry()
                para = nodes.paragraph()
                para += nodes.literal(cell, cell) if i == 0 and target is body else nodes.Text(cell)
                entry += para
                row += entry
            target += row
    return table


def blocks(schema: dict, title: str) -> list[tuple[str, str, dict]]:
    """(key path, definition name, definition) of every block, the root first, breadth first."""
    defs = schema.get("$defs", {})
    order, seen = [(title, None, schema)], set()
    queue = [(title, schema)]
    while queue:
        path, block = queue.pop(0)
        for key, field in block.get("properties", {}).items():
            for name, listed in _refs(field):
                if name in seen:
                    continue
                seen.add(name)
                sub = f"{key}[i]" if listed else key
                where = sub if path == title else f"{path}.{sub}"
                order.append((where, name, defs[name]))
                queue.append((where, defs[name]))
    return order


class SchemaReference(Directive):
    """``.. cpopt-schema::`` (no arguments): every block of a problem file, as tables."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        from cpopt.problem import schema as spec

        out: list[nodes.Node] = []
        parts = [
            (spec.ProblemSpec.model_json_schema(), "the file", "problem-file"),
            (spec.UrdfArmSpec.model_json_schema(), "arm (from a URDF)", "urdf-arm"),
        ]
        for root, title, prefix in parts:
            for path, name, block in blocks(root, title):
                ident = f"schema-{prefix}-{(name or 'root').lower()}"
                section = nodes.section(ids=[ident])
                heading = path if name is None else f"{path} ({name})"
                section += nodes.title(heading, heading)
                for paragraph in block.get("description", "").split("\n\n"):
                    if paragraph.strip():
                        section += _text(nodes.paragraph(), " ".join(paragraph.split()))
                required = set(block.get("required", []))
                rows = []
                for key, field in block.get("properties", {}).items():
                    default = field.get("default")
                    if key in required:
                        default = "required"
                    elif isinstance(default, dict) and _refs(field):
                        default = "the block's defaults"
                    else:
                        default = json.dumps(default)
                    rows.append((key, describe(field), default))
                section += _table(rows)
                out.append(section)
        return out


def setup(app):
    """Register the directive."""
    app.add_directive("cpopt-schema", SchemaReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
