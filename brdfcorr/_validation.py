"""One translator from pydantic validation errors to brdfcorr's one-line messages.

Parameter tables and chain configs are pydantic models; their errors become one line naming the
key path (``steps.fit.model``; for a parameter table's class ``class 2 (grass): params.w``), what
is wrong and, where the schema knows it, what is allowed: the keys of a section for an unknown
key, the values of a ``Literal`` (the registry's model names, built-in materials, ...).

Both kinds of document also share their building blocks here: :class:`StrictModel` (the base of
every section) and the field types that refuse YAML's booleans (:data:`Number`, :data:`Integer`,
:data:`PositiveInteger`).
"""

from __future__ import annotations

import reprlib
import typing
from collections.abc import Mapping
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError

from brdfcorr.errors import ParameterError

#: Tags pydantic inserts into error locations for the members of a union (``float``,
#: ``list[float]``, ``literal['mean','observed']``): not keys of the document.
_TYPE_TAGS = frozenset({"float", "int", "str", "bool"})
#: At most this many problems are listed in one message (a table of 20 000 bad classes is one line).
MAX_PROBLEMS = 10

_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = _REPR.maxlong = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxlevel = 3


def short_repr(value: object, limit: int = 80) -> str:
    """``repr(value)`` for a message, at most ``limit`` characters, in time bounded whatever the size
    of ``value`` (a document's input may be a 10 MB string or a list of a million values)."""
    try:
        text = _REPR.repr(value)
    except ValueError:  # an int of more than 4300 digits has no repr
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def key_text(key: object) -> str:
    """A document key as shown in messages: as is when plain, else quoted (``'\\n'``, ``''``), so a
    message stays one readable line whatever the keys of the document (a long key is shortened)."""
    text = key if isinstance(key, str) else short_repr(key)
    plain = text and len(text) <= 80 and text.isprintable() and text.strip() == text
    return text if plain else short_repr(key)


def check_flags(**flags: object) -> None:
    """Refuse a switch of the Python API that is not True or False: a string such as ``"no"`` or
    ``"false"`` is truthy, so the switch would be on (a view azimuth turned by 180 deg, wavelengths
    extrapolated) without a word. numpy booleans are booleans.

    Raises
    ------
    brdfcorr.errors.ParameterError
        ``{name} must be True or False, got {value}``.
    """
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise ParameterError(f"{name} must be True or False, got {short_repr(value)}")


def refuse_boolean(value: object) -> object:
    """A pydantic before-validator: a boolean where a number is expected is an error.

    YAML 1.1 reads yes, no, on, off, true and false as booleans, and pydantic's float and int
    would take a boolean as 1 or 0: a wrong number delivered silently. Put it on a union
    (``Annotated[float | list[Number], BeforeValidator(refuse_boolean)]``) to get one problem,
    not one per member of the union.
    """
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"expected a number, got the boolean {str(bool(value)).lower()} (YAML reads "
                         "unquoted yes, no, on, off, true and false as booleans)")
    return value


#: A float field that refuses booleans. Unlike pydantic's ``StrictFloat`` it still takes ints and
#: numeric strings (PyYAML reads ``1e-3``, without a dot, as a string).
Number = Annotated[float, BeforeValidator(refuse_boolean)]
#: An int field that refuses booleans (``class_lookup: {10: yes}`` is no class id 1).
Integer = Annotated[int, BeforeValidator(refuse_boolean)]
#: An int >= 1 that refuses booleans: a class id, a 1-based band.
PositiveInteger = Annotated[Integer, Field(ge=1)]


class StrictModel(BaseModel):
    """Base of the document models (parameter tables, chain configs): immutable, and a key the
    schema does not know is an error (``extra="forbid"``), not silently ignored."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def _location(loc: tuple) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{key_text(part)}" if text else key_text(part)
    return text


def _model_classes(annotation) -> list[type[BaseModel]]:
    """The pydantic model classes inside an annotation (Optional, Union, Annotated, list, dict)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found = []
    for argument in typing.get_args(annotation):
        found += _model_classes(argument)
    return found


def _union_tags(root: type[BaseModel]) -> set[str]:
    """The ``source`` tags of discriminated unions anywhere below ``root`` ("imagery", ...)."""
    tags: set[str] = set()
    seen: set[type[BaseModel]] = set()
    queue: list[type[BaseModel]] = [root]
    while queue:
        model = queue.pop()
        if model in seen:
            continue
        seen.add(model)
        source = model.model_fields.get("source")
        if source is not None:
            tags.update(a for a in typing.get_args(source.annotation) if isinstance(a, str))
        for field in model.model_fields.values():
            queue += _model_classes(field.annotation)
    return tags


def fields_at(root: type[BaseModel], loc: tuple) -> list[str] | None:
    """The allowed keys of the section of ``root`` at ``loc`` (None if it is not a section)."""
    candidates: list[type[BaseModel]] = [root]
    for part in loc:
        if isinstance(part, int):
            continue
        nested = []
        for model in candidates:
            if part in model.model_fields:
                nested += _model_classes(model.model_fields[part].annotation)
            else:  # a discriminated-union tag ("imagery") selects the member with that source
                for member in candidates:
                    source = member.model_fields.get("source")
                    if source is not None and part in typing.get_args(source.annotation):
                        nested.append(member)
        if not nested:
            return None
        candidates = list(dict.fromkeys(nested))
    return sorted({name for model in candidates for name in model.model_fields})


def _where(loc: tuple, data: object, tags: set[str]) -> tuple[str, bool]:
    """The location as text, and whether it names a parameter-table class (``class 2 (grass)``)."""
    clean: list[object] = []
    for part in loc:
        if isinstance(part, str) and (part in _TYPE_TAGS or "[" in part or (part in tags and clean)):
            continue
        clean.append(part)
    classes = data.get("classes") if isinstance(data, Mapping) else None
    if len(clean) >= 2 and clean[0] == "classes" and isinstance(clean[1], int) and isinstance(classes, list):
        entry = classes[clean[1]] if clean[1] < len(classes) else {}
        if isinstance(entry, Mapping):
            label = f"class {key_text(entry.get('id', f'#{clean[1] + 1}'))} ({key_text(entry.get('name', '?'))})"
            rest = _location(tuple(clean[2:]))
            return (f"{label}: {rest}" if rest else label), True
    return _location(tuple(clean)), False


def _message(item: Any, root: type[BaseModel]) -> str:
    kind = item["type"]
    if kind == "extra_forbidden":
        return f"unknown key; allowed keys: {', '.join(fields_at(root, tuple(item['loc'])[:-1]) or [])}"
    if kind == "missing":
        return "required key is missing"
    if kind == "literal_error":
        return f"{short_repr(item['input'])} is not allowed; allowed: {item.get('ctx', {}).get('expected', '')}"
    if kind == "union_tag_invalid":
        expected = item.get("ctx", {}).get("expected_tags", "")
        source = item["input"].get("source") if isinstance(item["input"], Mapping) else item["input"]
        return f"source {short_repr(source)} is not allowed; allowed: {expected}"
    if kind == "union_tag_not_found":
        tag = item.get("ctx", {}).get("discriminator", "'source'")
        return f"needs the key {tag}"
    message = item["msg"].removeprefix("Value error, ")
    if "input" in item and kind not in ("value_error", "assertion_error") and not isinstance(
            item["input"], (Mapping, list)):
        message += f" (got {short_repr(item['input'])})"
    return message


def describe_errors(error: ValidationError, root: type[BaseModel], data: object = None) -> str:
    """One line for all problems: ``where: what is wrong; allowed ...``, ``; ``-separated.

    Parameters
    ----------
    error : pydantic.ValidationError
    root : pydantic model class
        The document's schema (to list the allowed keys of a section).
    data : object, optional
        The document as parsed; its ``classes`` name a parameter table's classes by id and name.
    """
    tags = _union_tags(root)
    grouped: dict[tuple[str, bool], list[Any]] = {}
    for item in error.errors():
        grouped.setdefault(_where(tuple(item["loc"]), data, tags), []).append(item)
    lines = []
    for (where, is_class), items in grouped.items():
        kinds = [item["type"] for item in items]
        if len(items) > 1 and "literal_error" in kinds:  # every branch of "a number or a word" failed
            literal = items[kinds.index("literal_error")]
            number = " a number," if any(k in ("float_parsing", "float_type") for k in kinds) else ""
            messages = [f"{short_repr(literal['input'])} is not allowed; allowed:{number} "
                        f"{literal.get('ctx', {}).get('expected', '')}"]
        elif len(items) > 1 and all(k.endswith(("_type", "_parsing")) for k in kinds):  # every union branch
            messages = [f"invalid value {short_repr(items[0]['input'])}"]
        else:
            messages = [_message(item, root) for item in items]
        for message in messages:
            # Messages of a class's own validators already name the class.
            named = not where or (is_class and message.startswith("class "))
            lines.append(message if named else f"{where}: {message}")
    unique = list(dict.fromkeys(lines))
    if len(unique) > MAX_PROBLEMS:
        unique = unique[:MAX_PROBLEMS] + [f"and {len(unique) - MAX_PROBLEMS} more problems"]
    return "; ".join(unique)
