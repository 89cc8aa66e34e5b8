"""Griffe extension for the API page: a parameter's default that names a module constant
(``method=K.DEFAULT_METHOD``, ``band_hz=LOWBAND_HZ``) is shown as the constant's value
(``method="motion"``, ``band_hz=2.0``): the reader of a signature wants the value, not the
name of an internal constant. Only constants whose value is a literal (a string, a number,
a tuple of them) are substituted, and not a long text (a sentence reads better as its name);
anything else keeps its name.

Loaded by the first ``:::`` directive of docs/reference/api.md (``options: extensions``).
"""

from __future__ import annotations

import ast
from typing import Any

from griffe import Alias, Attribute, Class, Expr, Extension, Function, Module, Object


MAX_LENGTH = 40     # longer literals keep their constant's name


def _literal(value: Any) -> str | None:
    """The source text of ``value`` when it is a short literal, else None."""
    text = str(value)
    if len(text) > MAX_LENGTH:
        return None
    try:
        ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return None
    return text


class ConstantDefaults(Extension):
    """Replace constant names in parameter defaults by the constants' literal values."""

    def on_package(self, *, pkg: Module, loader: Any, **kwargs: Any) -> None:
        collection = loader.modules_collection
        self._walk(pkg, collection, set())

    def _walk(self, obj: Object, collection: Any, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        for member in list(obj.members.values()):
            if isinstance(member, Alias):
                continue
            if isinstance(member, Function):
                self._substitute(member, collection)
            elif isinstance(member, (Module, Class)):
                self._walk(member, collection, seen)

    @staticmethod
    def _substitute(func: Function, collection: Any) -> None:
        for param in func.parameters:
            default = param.default
            if not isinstance(default, Expr):
                continue
            try:
                target = collection[default.canonical_path]   # type: ignore[attr-defined]
            except Exception:  # noqa: BLE001  (not a name, or a name outside the package)
                continue
            if isinstance(target, Alias):
                try:
                    target = target.final_target
                except Exception:  # noqa: BLE001
                    continue
            if isinstance(target, Attribute) and target.value is not None:
                value = _literal(target.value)
                if value is not None:
                    param.default = value
