"""Click options made from a task's table of settings (:mod:`brdfcorr.tasks.options`): each
option of ``correct`` (and the other commands given a table) is written once, there.

:func:`setting_options` turns a :class:`~brdfcorr.tasks.options.Settings` table into a decorator
that adds one ``click.option`` per setting, in the table's order, as xclim makes its command line
from its registry.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from brdfcorr.cli._base import (
    CHUNK_SIZE,
    CLASS_MODEL,
    CLASS_NAME,
    FIT_MODEL_CHOICE,
    MODEL_CHOICE,
    NAME_RANGE,
    NAME_VALUE,
    READER_OPTION,
    distinct_names,
)
from brdfcorr.tasks.options import Setting, Settings

__all__ = ["CUSTOM_TYPES", "setting_options", "click_option"]

#: The command-line types of the ``"custom"`` settings, by their ``cli_type`` name.
CUSTOM_TYPES: dict[str, click.ParamType] = {
    "chunk": CHUNK_SIZE,
    "reader_option": READER_OPTION,
    "class_name": CLASS_NAME,
    "class_model": CLASS_MODEL,
    "name_value": NAME_VALUE,
    "name_range": NAME_RANGE,
    "model": MODEL_CHOICE,
    "fit_model": FIT_MODEL_CHOICE,
}


def _number_type(setting: Setting) -> click.ParamType:
    """``float`` or ``int``, as a click range where the setting has bounds."""
    integer = setting.kind == "int"
    if not setting.bounds():
        return click.INT if integer else click.FLOAT
    low = setting.ge if setting.ge is not None else setting.gt
    high = setting.le if setting.le is not None else setting.lt
    if integer:
        return click.IntRange(min=low, max=high, min_open=setting.gt is not None,  # type: ignore[arg-type]
                              max_open=setting.lt is not None)
    return click.FloatRange(min=low, max=high, min_open=setting.gt is not None, max_open=setting.lt is not None)


def _click_type(setting: Setting, custom: dict[str, click.ParamType]) -> click.ParamType | None:
    """The click type of ``setting`` (None for text and flags)."""
    if setting.kind == "path":
        return click.Path(dir_okay=False, path_type=Path)
    if setting.kind == "dir":
        return click.Path(file_okay=False, path_type=Path)
    if setting.kind in ("float", "int"):
        return _number_type(setting)
    if setting.kind == "choice":
        return click.Choice(list(setting.choices), case_sensitive=setting.case_sensitive)
    if setting.kind == "custom":
        if setting.cli_type not in custom:
            raise KeyError(f"setting {setting.name}: no command-line type {setting.cli_type!r}")
        return custom[setting.cli_type]
    return None


def click_option(setting: Setting, custom: dict[str, click.ParamType] | None = None) -> Callable:
    """One ``click.option`` from ``setting``; ``custom`` adds command-line types to :data:`CUSTOM_TYPES`."""
    keywords: dict[str, Any] = {"help": setting.help}
    click_type = _click_type(setting, {**CUSTOM_TYPES, **(custom or {})})
    if click_type is not None:
        keywords["type"] = click_type
    if setting.kind == "flag":
        keywords["is_flag"] = True
    elif (setting.default is not None and not setting.given_only) or setting.kind == "switch":
        keywords["default"] = setting.default
    given = {"nargs": setting.nargs != 1, "multiple": setting.multiple, "required": setting.required,
             "show_default": setting.show_default, "metavar": setting.metavar is not None,
             "envvar": setting.envvar is not None, "hidden": setting.hidden}
    for key, wanted in given.items():
        if wanted:
            keywords[key] = getattr(setting, key)
    if setting.envvar is not None:
        keywords["show_envvar"] = True
    if setting.multiple and getattr(click_type, "pairs", False):  # --fix k=0.25 --fix k=0.3: which one?
        keywords["callback"] = distinct_names
    return click.option(*setting.flags, setting.name, **keywords)


def setting_options(table: Settings, custom: dict[str, click.ParamType] | None = None) -> Callable:
    """A decorator adding the options of ``table`` to a command, in the table's order (``--help``'s)."""
    options = [click_option(setting, custom) for setting in table]

    def decorate(command):
        for option in reversed(options):
            command = option(command)
        return command

    return decorate
