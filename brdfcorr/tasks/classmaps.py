"""Class maps as files: NDVI strata from an image, a land-cover map brought onto an image grid.

The file-level side of :mod:`brdfcorr.strata` for ``brdfcorr classes ndvi`` and
``brdfcorr classes align``: read lazily, write a tiled GeoTIFF (uint8/uint16, nodata 0 = "no class")
atomically, with the provenance of the map in its tags.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from brdfcorr.errors import InputError
from brdfcorr.io import rasters
from brdfcorr.io.files import parse_yaml, read_document
from brdfcorr.io.paths import check_outputs, raster_files, refuse_existing
from brdfcorr.strata import NdviStrata, align_class_map, ndvi_strata, remap_classes

__all__ = ["ndvi_class_file", "NdviBins", "align_class_file", "read_lookup", "class_preparation", "describe_class_map",
           "tagged_class_names"]


def class_preparation(align: bool = False, lookup: Mapping[int, int] | None = None):
    """The class-map step before the grid check (:func:`brdfcorr.io.scene.open_scene`), or None.

    ``align``: bring a class map on another grid or CRS onto the image grid by nearest neighbour
    (:func:`brdfcorr.strata.align_class_map`); ``lookup``: remap its codes to table ids (e.g. ESA
    WorldCover codes, :func:`brdfcorr.strata.remap_classes`); an empty lookup (a chain's default
    ``class_lookup: {}``) is none.
    """
    lookup = lookup or None
    if align:
        return lambda classes, image: align_class_map(classes, image, lookup)
    if lookup:
        return lambda classes, image: remap_classes(classes, lookup)
    return None


def describe_class_map(classes: xr.DataArray, lookup: Mapping[int, int] | None) -> str:
    """Provenance of a prepared class map, for output tags ("" when used as it is)."""
    parts = []
    if "resampled_from_crs" in classes.attrs:
        parts.append(f"resampled from {classes.attrs['resampled_from_crs']} "
                     f"({classes.attrs['resampled_from_resolution']}, {classes.attrs['resampling']})")
    if lookup:
        parts.append("codes remapped " + ",".join(f"{code}:{ident}" for code, ident in sorted(lookup.items())))
    return "; ".join(parts)


def tagged_class_names(*class_maps: xr.DataArray) -> dict[int, str]:
    """Class names from the class maps' ``class_names`` tags (``"1:ndvi_-inf_0.10,2:..."``, as
    ``brdfcorr classes ndvi`` writes it; ``ID=NAME;...`` too), the first map's name of an id
    first; items that are no ``ID:NAME`` are skipped. A map remapped by a lookup has no such tag."""
    names: dict[int, str] = {}
    for classes in class_maps:
        text = str(classes.attrs.get("class_names", ""))
        for item in text.replace(";", ",").split(","):
            key, _, name = item.replace("=", ":", 1).partition(":")
            if key.strip().isdigit() and name.strip():
                names.setdefault(int(key), name.strip())
    return names


def read_lookup(path: str | os.PathLike) -> dict[int, int]:
    """A code -> class id lookup table from YAML (``{10: 3, 30: 3, 50: 1}``; ids 0..65535)."""
    path = Path(path)
    text = read_document(path, "lookup table", InputError)
    data = parse_yaml(text, f"lookup table {path}", InputError)
    if not isinstance(data, Mapping) or not data:
        raise InputError(f"lookup table {path}: expected a mapping of codes to class ids, e.g. '10: 3'")
    lookup = {}
    for code, ident in data.items():
        if not (isinstance(code, int) and isinstance(ident, int)) or isinstance(code, bool) or isinstance(
                ident, bool) or not 0 <= ident <= 65535:
            raise InputError(f"lookup table {path}: {code!r}: {ident!r} is not an integer code and a class id "
                             "in 0..65535")
        lookup[code] = ident
    return lookup


def _write_class_map(classes: xr.DataArray, output, *, inputs: Sequence[tuple], overwrite: bool, chunks: int,
                     tags: Mapping[str, str], compute: Mapping[str, object] | None = None) -> None:
    check_outputs({"output": output}, inputs)
    if not overwrite:
        refuse_existing(raster_files(output))
    Path(output).parent.mkdir(parents=True, exist_ok=True)
    rasters.write_rasters({output: classes}, geotiff=rasters.GeoTiffOutput(blocksize=chunks), tags=dict(tags),
                          **(compute or {}))


@dataclass(frozen=True)
class NdviBins:
    """How NDVI strata are cut (:func:`brdfcorr.strata.ndvi_strata`): fixed ``edges`` or scene
    ``percentiles`` (default: fixed edges 0.1, 0.3, 0.5, 0.7), and the classes of water and shadow
    pixels (0: no class)."""

    edges: Sequence[float] | None = None
    percentiles: Sequence[float] | None = None
    water_id: int = 0
    shadow_id: int = 0


def ndvi_class_file(
    image: str | os.PathLike, output: str | os.PathLike, *, bins: NdviBins = NdviBins(),
    wavelengths: Sequence[float] | None = None, scale: float | None = None, offset: float | None = None,
    chunks: int | None = None, overwrite: bool = False, scheduler: str | None = None,
    num_workers: int | None = None,
) -> NdviStrata:
    """Write a class map of NDVI strata of ``image`` (:func:`brdfcorr.strata.ndvi_strata`).

    Parameters
    ----------
    image, output : path-like
        Reflectance image (with band wavelengths, or give ``wavelengths`` [nm]) and the class map
        GeoTIFF to write (uint8, nodata 0).
    bins : NdviBins
        The strata's edges and the classes of water and shadow.
    scale, offset : float, optional
        Reflectance factor per stored unit and of a stored 0, replacing the file's
        (:func:`brdfcorr.io.rasters.open_image`). The image is checked for values that are no
        reflectance factors (:func:`brdfcorr.io.scale_check.check_reflectance_scale`, in
        :func:`~brdfcorr.strata.ndvi_strata`), with a given ``scale`` as well: the water and shadow
        tests are in reflectance factors.
    chunks : int, optional
        Chunk and tile size [pixels] (default :func:`brdfcorr.io.rasters.auto_chunk`).
    overwrite : bool, default False
        Replace an existing output.
    scheduler, num_workers : optional
        dask scheduler and its threads of the write (a chain's engine; default dask's); the scale
        check and the percentiles' pass use dask's default.

    Returns
    -------
    NdviStrata
        The strata: ``edges`` and ``names`` (id -> label) to pair with a parameter table.
    """
    chunks = rasters.auto_chunk(image) if chunks is None else int(chunks)
    with rasters.bounded_gdal_cache(image, chunks):  # every pass: the check, the percentiles, the write
        reflectance = rasters.open_image(image, chunks=chunks, wavelengths=wavelengths, scale=scale, offset=offset)
        compute = {"scheduler": scheduler, "num_workers": num_workers}
        strata = ndvi_strata(reflectance, edges=bins.edges, percentiles=bins.percentiles, water_id=bins.water_id,
                             shadow_id=bins.shadow_id)
        names = ",".join(f"{ident}:{name}" for ident, name in sorted(strata.names.items()))
        tags = {"brdf_class_map": f"NDVI strata of {Path(image).name}; edges "
                                  + ",".join(f"{edge:g}" for edge in strata.edges), "class_names": names}
        _write_class_map(strata.classes, output, inputs=[("image", image)], overwrite=overwrite, chunks=chunks,
                         tags=tags, compute=compute)
    return strata


def align_class_file(
    classes: str | os.PathLike, image: str | os.PathLike, output: str | os.PathLike, *,
    lookup: Mapping[int, int] | None = None, chunks: int | None = None, overwrite: bool = False,
    reads: Mapping[str, str | os.PathLike | None] | None = None,
) -> xr.DataArray:
    """Write a land-cover map brought onto the grid of ``image`` (nearest neighbour), its codes
    optionally remapped to table ids (:func:`brdfcorr.strata.align_class_map`).

    ``reads`` names further files the caller read (the lookup table file), never overwritten
    (:func:`brdfcorr.io.paths.check_outputs`). Returns the aligned (lazy) class map as written.
    """
    chunks = rasters.auto_chunk(image) if chunks is None else int(chunks)
    reflectance = rasters.open_image(image, chunks=chunks)
    aligned = align_class_map(rasters.open_classes(classes, chunks=chunks), reflectance, lookup)
    tags = {"brdf_class_map": f"{Path(classes).name}: {describe_class_map(aligned, lookup)}"}
    inputs = [("class map", classes), ("image", image), *(reads or {}).items()]
    _write_class_map(aligned, output, inputs=inputs, overwrite=overwrite, chunks=chunks, tags=tags)
    return aligned
