"""Per-scene name patterns of chain configs.

Per-scene sources (angles, class map) and output names are ``str.format`` patterns filled for
every input image with

``{dir}``    the image's directory
``{parent}`` the name of the image's directory (``scenes/line01/image.tif`` -> ``line01``)
``{stem}``   the image's file name without its suffix (``line01_image``)
``{scene}``  the scene name: the ``scene`` group of ``inputs.scene_regex`` matched on the file
             name (with ``scene_regex: '(?P<scene>.+)_image'``, ``line01``); without a regex the
             stem, or ``{parent}_{stem}`` when several images share the stem
"""

from __future__ import annotations

import string
from collections.abc import Iterator
from pathlib import Path

__all__ = ["PATTERN_FIELDS", "check_pattern", "format_pattern"]

#: Placeholders of per-scene name patterns.
PATTERN_FIELDS = ("dir", "parent", "stem", "scene")


def check_pattern(value: str, allowed=PATTERN_FIELDS) -> str:
    """A str.format pattern using only the allowed placeholders.

    The pattern is read as :meth:`str.format` reads it (:meth:`string.Formatter.parse`), so a
    conversion or a format spec (``{scene!s}``, ``{scene:>8}``) is accepted as it is there.

    Raises
    ------
    ValueError
        One line: the first placeholder that is not allowed (an attribute or an index of an allowed
        one, ``{scene.upper}``, and a positional ``{}`` included), or the pattern is no valid
        ``str.format`` pattern for strings (``{scene``, ``{scene:d}``).
    """
    try:
        bad = [name for name in _field_names(value) if name not in allowed]
    except ValueError as error:  # an unmatched brace
        raise ValueError(f"pattern {value!r}: {error}") from None
    if bad:
        raise ValueError(
            f"pattern {value!r} uses {{{bad[0]}}}; allowed placeholders: "
            + ", ".join(f"{{{name}}}" for name in allowed)
        )
    try:
        value.format(**{name: "x" for name in allowed})
    except ValueError as error:  # a format spec strings do not take
        raise ValueError(f"pattern {value!r}: {error}") from None
    return value


def _field_names(pattern: str) -> Iterator[str]:
    """The field names of a str.format pattern, in order, those nested in format specs
    (``{scene:>{width}}``) included."""
    for _, name, spec, _ in string.Formatter().parse(pattern):
        if name is not None:
            yield name
        if spec:
            yield from _field_names(spec)


def format_pattern(pattern: str, image: Path, scene: str) -> str:
    """Fill a name pattern for one image (``{dir}``, ``{parent}``, ``{stem}``, ``{scene}``)."""
    return pattern.format(dir=str(image.parent), parent=image.parent.name, stem=image.stem, scene=scene)
