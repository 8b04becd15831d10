"""What an input path names: a product (a folder, a STAC item file) or a raster file.

Told from the path alone (no file is read), so that a chain's plan and the command line sort their
inputs without loading the product readers (:mod:`.folders`, :mod:`.stac`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from brdfcorr.errors import InputError

__all__ = ["is_stac_item", "is_product", "products_among"]


def is_stac_item(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a STAC item file (a ``.json`` file), not a product folder."""
    return Path(path).suffix.lower() == ".json" and not Path(path).is_dir()


def is_product(path: str | os.PathLike) -> bool:
    """Whether an input path names a product rather than a raster file: a folder (a Sentinel-2
    SAFE, a Landsat Collection-2 folder) or a STAC item file (``.json``)."""
    return Path(path).is_dir() or is_stac_item(path)


def products_among(images: Sequence[str | os.PathLike], given: Mapping[str, object]) -> bool:
    """Whether the inputs ``images`` are products (:func:`is_product`), all of them.

    Raises InputError for a mix of products and files, and for the options in ``given`` ({flag:
    its value; None, False or empty where not given: a number 0 is given, ``--offset 0`` was
    ignored}) that products bring themselves (angles, scaling, wavelengths).
    """
    found = [is_product(image) for image in images]
    if not any(found):
        return False
    if not all(found):
        raise InputError(f"{images[found.index(False)]} is a file and {images[found.index(True)]} a product: give "
                         "product folders (the dates of a series) or image files, not both")
    named = [flag for flag, value in given.items()
             if not (value is None or value is False or (isinstance(value, (tuple, list, str)) and not value))]
    if named:
        raise InputError(f"{', '.join(named)}: product folders bring their own angles, scaling and wavelengths; "
                         f"leave {'it' if len(named) == 1 else 'them'} out")
    return True
