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

import re
from pathlib import Path

__all__ = ["PATTERN_FIELDS", "check_pattern", "format_pattern"]

#: Placeholders of per-scene name patterns.
PATTERN_FIELDS = ("dir", "parent", "stem", "scene")


def check_pattern(value: str, allowed=PATTERN_FIELDS) -> str:
    """A str.format pattern using only the allowed placeholders (ValueError naming the first other)."""
    names = re.findall(r"(?<!\{)\{([^{}]*)\}", value)
    bad = [name for name in names if name not in allowed]
    if bad:
        raise ValueError(
            f"pattern {value!r} uses {{{bad[0]}}}; allowed placeholders: "
            + ", ".join(f"{{{name}}}" for name in allowed)
        )
    return value


def format_pattern(pattern: str, image: Path, scene: str) -> str:
    """Fill a name pattern for one image (``{dir}``, ``{parent}``, ``{stem}``, ``{scene}``)."""
    return pattern.format(dir=str(image.parent), parent=image.parent.name, stem=image.stem, scene=scene)
