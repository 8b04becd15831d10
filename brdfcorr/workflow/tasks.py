"""The tasks on files that the CLI and chains share: one library function each.

- :func:`correct_files`: normalize one image (``brdfcorr correct``, a chain's correct step);
- :func:`fit_measurement_file`: fit a goniometer table (``brdfcorr fit``, a chain's goniometer fit);
- :func:`fit_class_files`: fit per-class parameters from scenes (``brdfcorr fit-classes``, a chain's
  imagery fit).

They read and write files but print nothing: the CLI shows their results, chains report them.
Warnings of the fits are collected into the results (``warnings``), one line each.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
import rasterio
import xarray as xr

from brdfcorr import __version__
from brdfcorr.correct import (
    QA_FACING_AWAY,
    QA_LIMITED,
    QA_NODATA,
    QA_TOPOGRAPHY_UNCORRECTED,
    describe_limits,
    normalize,
    qa_counts,
    resolve_reference,
)
from brdfcorr.errors import BrdfcorrError, BrdfcorrWarning, InputError, ParameterError
from brdfcorr.fit.classes import ClassFitResult, ClassFitWarning, GuardRails, fit_classes
from brdfcorr.fit.goniometer import FitResult, FitWarning, fit_measurements, spectral_table_entry
from brdfcorr.fit.measurements import Measurements, filter_measurements, read_measurements, selection_mask
from brdfcorr.io import rasters, writer
from brdfcorr.io.paths import check_outputs, refuse_existing
from brdfcorr.params import ParameterTable, ReferenceGeometry
from brdfcorr.strata import align_class_map, remap_classes
from brdfcorr.terrain import SlopeAspect, slope_aspect, slope_aspect_layers
from brdfcorr.topographic import (
    TOPO_QA_FIT_REJECTED,
    TOPO_QA_LIMITED,
    TOPO_QA_SHADOWED,
    frame_conflict,
    topographic_correction,
)
from brdfcorr.uncertainty import correction_uncertainty

if TYPE_CHECKING:  # optional dependency, for the annotation only
    import distributed

__all__ = [
    "correct_files",
    "Terrain",
    "fit_measurement_file",
    "MeasurementFit",
    "fit_class_files",
    "SceneFiles",
    "ImageryFit",
    "class_preparation",
]


def class_preparation(align: bool = False, lookup: Mapping[int, int] | None = None):
    """The class-map step before the grid check (:func:`brdfcorr.io.rasters.open_scene`), or None.

    ``align``: bring a class map on another grid or CRS onto the image grid by nearest neighbour
    (:func:`brdfcorr.strata.align_class_map`); ``lookup``: remap its codes to table ids (e.g. ESA
    WorldCover codes, :func:`brdfcorr.strata.remap_classes`).
    """
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


# ------------------------------------------------------------------------------------ correct
@dataclass(frozen=True)
class Terrain:
    """Tilted surfaces in a correction (``docs/terrain.md``): where slope and aspect come from and
    what is done with them.

    Attributes
    ----------
    slope_aspect : path-like, optional
        A 2-band raster of slope and aspect [deg] on the image grid (band descriptions naming
        ``slope`` and ``aspect`` decide which is which, else that order), or an ENVI ``obs_ort``
        file (its bands "Slope" and "Aspect", :func:`brdfcorr.io.sensors.envi.read_envi_obs_terrain`).
    dem : path-like, optional
        Or a DEM/DSM [m] on the image grid in a projected CRS: slope and aspect by Horn's
        differences (:func:`brdfcorr.terrain.slope_aspect`). Give one of the two.
    topographic : {"cosine", "c", "scs", "scs+c", "none"}, default "cosine"
        Illumination correction before the BRDF step (:func:`brdfcorr.topographic.topographic_correction`;
        C fitted per class and band from the image for ``"c"`` and ``"scs+c"``).
    brdf_frame : {"surface", "horizontal"}, default "surface"
        Evaluate the BRDF in each surface's own frame (the observed geometry rotated by slope and
        aspect; the reference stays horizontal) or in the horizontal frame. ``"surface"`` takes
        the illumination's cos i into account itself only with ``"cosine"`` (or ``"none"``) before
        it; the empirical C of ``"c"``/``"scs+c"`` absorbs part of the BRDF's slope dependence, so
        those go with ``"horizontal"`` (combining them corrects the illumination twice, 15 % off
        between the sides of a synthetic hill in ``tests/test_terrain.py``).
    """

    slope_aspect: str | os.PathLike | None = None
    dem: str | os.PathLike | None = None
    topographic: Literal["cosine", "c", "scs", "scs+c", "none"] = "cosine"
    brdf_frame: Literal["surface", "horizontal"] = "surface"

    def __post_init__(self):
        if (self.slope_aspect is None) == (self.dem is None):
            raise InputError("terrain: give slope and aspect (a 2-band raster or an obs file) or a DEM, one of them")
        conflict = frame_conflict(self.topographic, self.brdf_frame)
        if conflict:
            raise InputError(f"terrain: {conflict}")

    @property
    def inputs(self) -> list[tuple[str, object]]:
        return [("slope/aspect raster", self.slope_aspect), ("DEM", self.dem)]

    def open(self, like: xr.DataArray, chunks: int) -> SlopeAspect:
        """Slope and aspect [deg] (y, x) on ``like``'s grid, lazily."""
        if self.dem is not None:
            dem = rasters.open_layer(self.dem, "DEM", chunks)
            if dem.shape[0] != 1:
                raise InputError(f"DEM file {self.dem} has {dem.shape[0]} bands; it needs 1")
            surface = slope_aspect(dem[0])
        elif _is_envi(self.slope_aspect):
            from brdfcorr.io.sensors.envi import read_envi_obs_terrain  # sensors import this module's layer

            layers = read_envi_obs_terrain(self.slope_aspect, like=like)
            surface = SlopeAspect(layers["slope"], layers["aspect"])
        else:
            surface = slope_aspect_layers(rasters.open_layer(self.slope_aspect, "slope/aspect", chunks))
        rasters.check_same_grid({"image": like, "slope": surface.slope, "aspect": surface.aspect})
        return surface

    def apply(self, scene: rasters.SceneData, chunks: int, limits):
        """The reflectance after the topographic step, the slope and aspect layers for
        :func:`brdfcorr.normalize` (none in the horizontal frame) and the topographic result."""
        slope, aspect = self.open(scene.reflectance, chunks)
        reflectance, topographic = scene.reflectance, None
        if self.topographic != "none":
            topographic = topographic_correction(
                reflectance, scene.angles["sza"], scene.angles["saa"], slope, aspect, method=self.topographic,
                classes=scene.classes, limits=limits,
            )
            reflectance = topographic.reflectance
        surface = {"slope": slope, "aspect": aspect} if self.brdf_frame == "surface" else {}
        return reflectance, surface, topographic


def _is_envi(path) -> bool:
    try:
        with rasterio.open(path) as dataset:
            return dataset.driver == "ENVI"
    except rasterio.errors.RasterioIOError:
        return False  # the reader names the file


def _merged_qa(qa: xr.DataArray, topographic_qa: xr.DataArray) -> xr.DataArray:
    """The topographic step's flags in the correction's QA layer: sun behind the surface ->
    ``facing_away``, illumination factor clipped -> ``limited``, C fit rejected ->
    ``topography_uncorrected`` (nodata is the BRDF step's own: the step writes NaN there)."""
    flags = xr.zeros_like(qa)
    for topographic_flag, flag in ((TOPO_QA_SHADOWED, QA_FACING_AWAY), (TOPO_QA_LIMITED, QA_LIMITED),
                                   (TOPO_QA_FIT_REJECTED, QA_TOPOGRAPHY_UNCORRECTED)):
        flags = flags | xr.where((topographic_qa & topographic_flag) > 0, flag, 0).astype(np.uint8)
    merged = qa | flags
    merged.attrs = qa.attrs
    return merged


def correct_files(
    image, output, *, params, angles=None, sza=None, saa=None, vza=None, vaa=None, classes,
    reference: ReferenceGeometry | dict | None = None, qa_output=None, wavelengths=None,
    extrapolate: bool = False, limits=(0.2, 5.0), unknown: Literal["keep", "nan"] = "keep",
    flip_view_azimuth: bool = False, chunks: int | None = None, compress: str = "deflate",
    cog: bool = False, callbacks=(), table_source: str | None = None,
    angles_kind: str = "geotiff", angle_options: dict | None = None, overwrite: bool = True,
    align_classes: bool = False, class_lookup: Mapping[int, int] | None = None,
    scheduler: str | distributed.Client | None = None, num_workers: int | None = None,
    scale: float | None = None, offset: float | None = None,
    reads: Mapping[str, str | os.PathLike | None] | Sequence = (), fingerprint: str | None = None,
    output_format: Literal["GTiff", "ENVI"] = "GTiff", interleave: Literal["bsq", "bil"] = "bsq",
    uncertainty_output=None, terrain: Terrain | None = None, output_type: Literal["float", "input"] = "float",
) -> dict[str, object]:
    """Normalize an image file: read image, angles and class map, write the corrected image.

    Inputs are opened lazily in chunks and checked once (:func:`brdfcorr.io.rasters.open_scene`:
    one grid check, one pass over the angle data that also gives the scene-mean sun zenith),
    normalized with :func:`brdfcorr.normalize` and written tiled and compressed, chunk by chunk, to
    a temporary name renamed when complete, with band descriptions and provenance tags (reference
    geometry, limits, parameter table, brdfcorr version). The optional QA layer is written in the
    same pass.

    The image's stored values are read as reflectance factors: scaled with the file's per-band GDAL
    scale and offset (``reflectance = stored * scale + offset``), or with ``scale``/``offset`` where
    given. The output holds reflectance factors (float32, float64 for a float64 input, no GDAL
    scale/offset) and records the scaling applied in the tags ``brdf_input_scale`` and
    ``brdf_input_offset`` (one value, or one per band comma-separated); with ``output_type="input"``
    an integer input's type instead, with its scale, offset and nodata.

    Parameters
    ----------
    image, output : path-like
        Input reflectance raster and output raster (``output_format``).
    params : ParameterTable or path-like
        The parameter table (a path is loaded with :meth:`ParameterTable.load`).
    angles : path-like, optional
        4-band raster sza, saa, vza, vaa [deg]; or give ``sza``, ``saa``, ``vza``, ``vaa`` files.
    classes : path-like
        Class map raster.
    reference, wavelengths, extrapolate, limits, unknown, flip_view_azimuth :
        As for :func:`brdfcorr.normalize`. A ``"mean"`` reference sun zenith is recorded as a
        number in the tags.
    qa_output : path-like, optional
        Where to write the QA layer (uint8 flags).
    chunks : int, optional
        Spatial chunk and tile size [pixels]; by default :func:`brdfcorr.io.rasters.auto_chunk`
        (512 for up to 16 bands, smaller for more, so that memory does not grow with the band count).
    compress : str, default "deflate"
    cog : bool, default False
        Write Cloud-Optimized GeoTIFFs.
    callbacks : sequence
        Dask callbacks active while computing (a progress bar).
    table_source : str, optional
        Where an in-memory ``params`` came from, for the provenance tag.
    angles_kind : str, default "geotiff"
        ``"geotiff"`` for angle rasters on the image grid; otherwise a sensor source kind of
        :func:`brdfcorr.io.sensors.read_angles` (``"envi_obs"``, ``"sentinel2"``, ``"landsat"``,
        ``"solar"``) read from ``angles`` onto the image grid with ``angle_options``.
    overwrite : bool, default True
        Replace existing outputs; with False an existing output is an :class:`OutputError`
        (the CLI's default). An input is never overwritten.
    align_classes : bool, default False
        Accept a class map on another grid or CRS: resample it onto the image grid by nearest
        neighbour (recorded in the tag ``brdf_class_map``). Off by default: a class map on another
        grid is an error.
    class_lookup : mapping of int to int, optional
        Remap the class map's codes to table ids (codes not in it: no class).
    scheduler, num_workers : optional
        dask scheduler of the computations and its number of workers (as for
        :func:`dask.compute`; default: dask's), e.g. ``"threads"`` and 2 inside a process or
        cluster worker, where several scenes may run side by side; a ``distributed.Client``
        spreads the scene's chunks over the cluster's workers (:mod:`brdfcorr.io.writer`).
    scale, offset : float, optional
        Reflectance factor per stored unit and of a stored 0, for images that do not tag them
        (e.g. 0.0001 for reflectance stored as 0-10000); a given value replaces the file's
        (:func:`brdfcorr.io.rasters.open_image`). Without ``scale`` a sample of the image is
        checked for raw counts (:func:`brdfcorr.io.rasters.check_reflectance_scale`, a few chunks
        read, not a pass); a given scale is trusted.
    reads : mapping of name to path, or sequence of paths, optional
        Further files the caller read for this correction (the parameter table file, a class
        lookup table): like the inputs, never overwritten (:func:`brdfcorr.io.paths.check_outputs`).
    fingerprint : str, optional
        Canonical JSON of everything the output depends on
        (:func:`brdfcorr.workflow.plan.scene_fingerprint`), written in the tags
        ``brdf_fingerprint`` (its SHA-256, hex) and ``brdf_fingerprint_content``: a resumed chain
        redoes an output whose fingerprint is not the one it would write.
    output_format : {"GTiff", "ENVI"}, default "GTiff"
        Format of ``output`` (the QA layer is always a GeoTIFF); its extension must fit
        (:func:`brdfcorr.io.writer.check_format`: ``.tif``/``.tiff``; ``.img``, ``.bsq``, ``.bil``,
        ``.dat`` or none). ENVI: uncompressed, a header ``.hdr`` beside it (map info, coordinate
        system, band names, ``data ignore value = nan``, ``wavelength``/``fwhm`` [nm] where known)
        and the tags in ``.aux.xml``.
    interleave : {"bsq", "bil"}, default "bsq"
        Interleave of an ENVI output.
    uncertainty_output : path-like, optional
        Where to write the per-pixel 1-sigma of the corrected reflectance (a GeoTIFF like the
        output, same pass; :func:`brdfcorr.uncertainty.correction_uncertainty`): NaN for classes
        whose table entry has no ``fit:`` covariance.
    terrain : Terrain, optional
        Tilted surfaces: slope and aspect, the topographic step and the BRDF's frame.
    output_type : {"float", "input"}, default "float"
        ``"float"``: reflectance factors as float32 (float64 for a float64 input). ``"input"``: an
        integer input's own type, scale, offset and nodata (GDAL scale/offset tags; a 2.4x smaller
        file for int16): ``stored = round((reflectance - offset) / scale)``
        (:func:`brdfcorr.io.writer.encode_integers`); pixels whose corrected value does not fit
        the type in some band are nodata there and flagged ``nodata`` (never wrapped or clipped).
        A float input is written as float either way.

    Returns
    -------
    dict
        Pixel counts (:func:`brdfcorr.correct.qa_counts`) plus ``reference`` (the geometry used)
        and, with a topographic step, ``topographic``: its method and the C fit per class and band.

    Warns
    -----
    BrdfcorrWarning
        Once per class given as a library ``material`` (a fit at one wavelength) when a band
        centre is more than 100 nm from that wavelength (:meth:`ClassEntry.wavelength_caveat`).

    Raises
    ------
    InputError
        A missing, unreadable or malformed input (named): wrong band counts, a float class map,
        angles that look like radians or hold no zenith in [0, 90)
        (:func:`brdfcorr.io.rasters.check_angles`; single pixels outside the domain are flagged,
        not an error), an image that holds no reflectance factors after scaling (raw counts without
        ``scale``), an output that is the same file as an input
        (:class:`brdfcorr.io.paths.InputOverwriteError`).
    GridMismatchError
        A layer not on the image's grid (shape, transform or CRS).
    ParameterError
        The table does not fit the image's bands (names the table, the class and the parameter).
    OutputError
        An existing output without ``overwrite``, an output that is no regular file or the same
        file as the other output, or a failed write (disk full); nothing is left at the output paths.
    """
    inputs = [("image", image), ("angles", None if angles_kind == "solar" else angles), ("sza raster", sza),
              ("saa raster", saa), ("vza raster", vza), ("vaa raster", vaa), ("class map", classes),
              ("parameter table", None if isinstance(params, ParameterTable) else params)]
    inputs += list(reads.items()) if isinstance(reads, Mapping) else list(reads)
    inputs += terrain.inputs if terrain is not None else []
    _check_correct_outputs(output, qa_output, output_format, inputs, overwrite, uncertainty_output)
    table_path = table_source
    if not isinstance(params, ParameterTable):
        table_path = str(params)
        params = ParameterTable.load(params)
    chunks = rasters.auto_chunk(image) if chunks is None else int(chunks)
    scene = rasters.open_scene(
        image, classes, angles, angles_kind=angles_kind, angle_options=angle_options,
        sza=sza, saa=saa, vza=vza, vaa=vaa, chunks=chunks, wavelengths=wavelengths,
        scale=scale, offset=offset, prepare_classes=class_preparation(align_classes, class_lookup),
        scheduler=scheduler, num_workers=num_workers,
    )
    _warn_wavelength_caveats(params, scene.reflectance)
    if scale is None:  # a given scale is the user's word; else catch raw counts before the correction pass
        rasters.check_reflectance_scale(scene.reflectance, str(image), scheduler=scheduler, num_workers=num_workers)
    reference = resolve_reference(reference, params)
    source = "fixed" if not isinstance(reference.sza, str) else reference.sza
    if reference.sza == "mean":
        mean = scene.statistics.means["sza"]
        if not np.isfinite(mean):
            where = scene.angles["sza"].encoding.get("source", "sza")
            raise InputError(f"{where}: no valid solar zenith for the scene mean")
        reference = reference.model_copy(update={"sza": float(mean)})

    layers = scene.angles
    reflectance, surface, topographic = scene.reflectance, {}, None
    if terrain is not None:
        reflectance, surface, topographic = terrain.apply(scene, chunks, limits)
    arguments = dict(
        reflectance=reflectance, classes=scene.classes, sza=layers["sza"], saa=layers["saa"], vza=layers["vza"],
        vaa=layers["vaa"], params=params, reference=reference, limits=limits, extrapolate=extrapolate,
        flip_view_azimuth=flip_view_azimuth, **surface,
    )
    try:
        corrected, qa = normalize(**arguments, unknown=unknown)
        sigma = correction_uncertainty(**arguments) if uncertainty_output is not None else None
    except ParameterError as error:  # the table does not fit the image's bands: name both files
        raise ParameterError(f"{table_path or 'parameter table'}: {error} (image {image})") from None
    if topographic is not None:
        qa = _merged_qa(qa, topographic.qa)
    corrected = corrected.drop_vars("wavelength", errors="ignore").rio.write_nodata(np.nan, encoded=True)
    corrected.attrs["long_name"] = _band_descriptions(scene.reflectance)
    for name in ("scale_factor", "add_offset"):  # the output holds physical values
        corrected.attrs.pop(name, None)
    for name in _envi_header_items(image, corrected.attrs):  # an ENVI input's header is no tag of the output
        corrected.attrs.pop(name)
    stored = np.dtype(scene.reflectance.encoding.get("rasterio_dtype", scene.reflectance.dtype))
    if output_type == "input" and stored.kind in "iu":
        corrected, out_of_range = writer.encode_integers(
            corrected, stored, scene.reflectance.attrs["brdf_input_scale"],
            scene.reflectance.attrs["brdf_input_offset"], scene.reflectance.encoding.get("_FillValue"),
        )
        qa = (qa | xr.where(out_of_range, QA_NODATA, 0).astype(np.uint8)).assign_attrs(qa.attrs)
    tags = {
        "brdf_reference": reference.describe(),
        "brdf_reference_sza_source": source,
        "brdf_limits": describe_limits(limits),
        "brdf_parameter_table": table_path or "(in memory)",
        "brdf_parameter_table_content": json.dumps(params.to_dict(), separators=(",", ":")),
        **_scene_tags(scene, class_lookup, fingerprint),
    }
    envi = {}
    if output_format == "ENVI":
        coords = scene.reflectance.coords
        envi[output] = writer.EnviOutput(
            interleave=interleave,
            wavelength=coords["wavelength"].values.tolist() if "wavelength" in coords else None,
            fwhm=np.asarray(coords["fwhm"].values).tolist() if "fwhm" in coords else None,
        )
    targets = {output: corrected}
    if qa_output is not None:
        targets[qa_output] = qa
    if sigma is not None:
        sigma = sigma.drop_vars("wavelength", errors="ignore").rio.write_nodata(np.nan, encoded=True)
        sigma.attrs["long_name"] = corrected.attrs["long_name"]
        targets[uncertainty_output] = sigma
    counts = rasters.write_rasters(
        targets, compress=compress, blocksize=chunks, cog=cog, tags=tags,
        compute_with=qa_counts(qa), callbacks=callbacks, gdal_cache=rasters.gdal_cache_bytes(image, chunks),
        scheduler=scheduler, num_workers=num_workers, envi=envi,
    )
    result: dict[str, object] = {**{key: int(value) for key, value in counts.items()}, "reference": reference}
    if topographic is not None:
        table = topographic.c_table
        result["topographic"] = {"method": terrain.topographic,  # type: ignore[union-attr]
                                 "c": [] if table is None else table.to_dict(orient="records")}
    return result


def _scene_tags(scene: rasters.SceneData, class_lookup, fingerprint: str | None) -> dict[str, str]:
    """The output's tags that describe the scene: input scaling, class map, fingerprint, wavelengths."""
    tags = {
        "brdf_input_scale": _describe_scaling(scene.reflectance.attrs["brdf_input_scale"]),
        "brdf_input_offset": _describe_scaling(scene.reflectance.attrs["brdf_input_offset"]),
        "brdfcorr_version": __version__,
    }
    class_map_note = describe_class_map(scene.classes, class_lookup)
    if class_map_note:
        tags["brdf_class_map"] = class_map_note
    if fingerprint is not None:  # what a resumed chain compares (brdfcorr.workflow.plan)
        tags["brdf_fingerprint"] = hashlib.sha256(fingerprint.encode()).hexdigest()
        tags["brdf_fingerprint_content"] = fingerprint
    if "wavelength" in scene.reflectance.coords:
        tags["wavelength"] = ",".join(f"{w:g}" for w in scene.reflectance["wavelength"].values)
        tags["wavelength_units"] = "nm"
    return tags


def _warn_wavelength_caveats(table: ParameterTable, reflectance: xr.DataArray) -> None:
    """A :class:`BrdfcorrWarning` per class whose single-wavelength fit (a library material) is
    applied to far-away bands (:meth:`brdfcorr.params.ClassEntry.wavelength_caveat`)."""
    if "wavelength" not in reflectance.coords:  # band centres unknown: nothing to compare
        return
    for entry in table.classes:
        caveat = entry.wavelength_caveat(reflectance["wavelength"].values)
        if caveat is not None:
            warnings.warn(caveat, BrdfcorrWarning, stacklevel=3)


def _check_correct_outputs(output, qa_output, output_format: str, inputs: list, overwrite: bool,
                           uncertainty_output=None) -> None:
    """The output guard, formats and extensions, and existing outputs (``overwrite``)."""
    outputs = {"output": output, "QA output": qa_output, "uncertainty output": uncertainty_output}
    if output_format == "ENVI":  # never the header of an ENVI input (image.img and image.bsq share image.hdr)
        outputs["output header"] = writer.envi_header_path(output)
        named = [item if isinstance(item, tuple) else ("input", item) for item in inputs]
        inputs = inputs + [(f"{name} header", writer.envi_header_path(path)) for name, path in named
                           if path is not None and writer.envi_header_path(path).exists()]
    check_outputs(outputs, inputs)
    writer.check_format(output, output_format)
    for path, what in ((qa_output, "QA output"), (uncertainty_output, "uncertainty output")):
        if path is not None:
            writer.check_format(path, "GTiff", what)
    if not overwrite:
        refuse_existing([output, qa_output, uncertainty_output])


def _envi_header_items(image, attrs: Mapping) -> list[str]:
    """The attrs that rioxarray took from an ENVI input's header (its ENVI metadata domain, and the
    ``Band_N`` band names and ``wavelength_units`` GDAL mirrors into the default domain): header
    fields of the input, not provenance of the output. None for another format."""
    try:
        with rasterio.open(image) as dataset:
            if dataset.driver != "ENVI":
                return []
            header = set(dataset.tags(ns="ENVI")) | {"wavelength", "wavelength_units", "fwhm"}
    except rasterio.errors.RasterioIOError:
        return []
    return [name for name in attrs if name in header or re.fullmatch(r"Band_\d+", name)]


def _describe_scaling(value: float | Sequence[float]) -> str:
    """A scale or offset of :func:`brdfcorr.io.rasters.open_image` as a tag: ``"0.0001"``, or one
    value per band comma-separated (shortest exact form)."""
    return ",".join(repr(float(v)) for v in np.atleast_1d(value))


def _band_descriptions(reflectance: xr.DataArray) -> tuple[str, ...]:
    """The output's band descriptions: the input's own where every band has one, else the band
    centres ("560 nm"), else "band 1" ... (not the array's name on every band)."""
    n_bands = reflectance.sizes[reflectance.dims[0]]
    described = reflectance.attrs.get("long_name")
    if isinstance(described, (tuple, list)) and len(described) == n_bands and all(described):
        return tuple(str(text) for text in described)
    if "wavelength" in reflectance.coords:
        return tuple(f"{wavelength:g} nm" for wavelength in reflectance["wavelength"].values)
    return tuple(f"band {number}" for number in range(1, n_bands + 1))


# ---------------------------------------------------------------------------- goniometer fit
@dataclass
class MeasurementFit:
    """The fit of one goniometer table (:func:`fit_measurement_file`).

    Attributes
    ----------
    path : Path
        The measurement file.
    everything, fitted : Measurements
        All measurements (of the chosen wavelength) and those selected for the fit.
    keep : ndarray of bool
        Which of ``everything`` were fitted.
    selection : str
        The selection in words ("phi >= 90 deg"), empty when every measurement is fitted.
    results : dict of float or None to FitResult
        One fit per wavelength (key None for a table without wavelengths).
    warnings : list of str
        Identifiability and convergence warnings, prefixed with the wavelength where there are
        several.
    """

    path: Path
    everything: Measurements
    fitted: Measurements
    keep: np.ndarray
    selection: str
    results: dict[float | None, FitResult]
    warnings: list[str] = field(default_factory=list)

    @property
    def source(self) -> str:
        """What was fitted, for the table's ``fit:`` block: ``"brdfcorr fit tiles.csv (torrance_sparrow;
        fixed k=0.25; phi >= 90)"``."""
        first = next(iter(self.results.values()))
        details = [first.model.name]
        if first.fixed:
            details.append("fixed " + ", ".join(f"{key}={value:g}" for key, value in first.fixed.items()))
        if self.selection:
            details.append(self.selection)
        return f"brdfcorr fit {self.path.name} ({'; '.join(details)})"

    def table_entry(self, class_id: int, name: str) -> dict:
        """The fit as a class of a parameter table (spectral where there are several wavelengths),
        with its ``fit:`` provenance block (:meth:`brdfcorr.fit.FitResult.fit_record`)."""
        if len(self.results) > 1:
            return spectral_table_entry(self.results, class_id, name, self.source)
        return next(iter(self.results.values())).table_entry(class_id, name, self.source)

    def report(self) -> list[dict]:
        """JSON-friendly fits per wavelength: params, errors, reduced chi^2."""
        return [
            {"wavelength": wavelength, "params": dict(result.params),
             "errors": {k: float(v) for k, v in result.errors.items()}, "reduced_chi2": float(result.reduced_chi2)}
            for wavelength, result in self.results.items()
        ]


def fit_measurement_file(
    path: str | os.PathLike, model: str, *, fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None, bounds: Mapping[str, tuple[float, float]] | None = None,
    min_phi: float | None = None, max_phi: float | None = None, max_zenith: float | None = None,
    wavelength: float | None = None,
) -> MeasurementFit:
    """Fit a registry model to a goniometer measurement table, one fit per wavelength.

    Parameters
    ----------
    path : path-like
        CSV with columns ``theta_i, theta_r, phi, brdf[, sigma, wavelength]`` [deg, sr^-1]
        (:func:`brdfcorr.fit.measurements.read_measurements`).
    model : str
        Registered surface model.
    fixed, initial, bounds :
        As for :func:`brdfcorr.fit.fit_brdf` (paper 003 fixes k = 0.25).
    min_phi, max_phi, max_zenith : float, optional
        Fit only these measurements [deg] (paper 003: ``min_phi=90``).
    wavelength : float, optional
        Fit only this wavelength [nm] of a table with a wavelength column.
    """
    everything = read_measurements(path)
    if wavelength is not None:
        everything = everything.at_wavelength(wavelength)
    limits = {"min_phi": min_phi, "max_phi": max_phi, "max_zenith": max_zenith}
    fitted = filter_measurements(everything, **limits)
    keep, selection = selection_mask(everything, **limits)
    options = {"fixed": fixed or None, "initial": initial or None, "bounds": bounds or None}
    bands = fitted.wavelengths or [None]
    results, notes = {}, []
    for band in bands:
        subset = fitted if band is None else fitted.at_wavelength(band)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FitWarning)
            results[band] = fit_measurements(model, subset, **options)
        where = "" if band is None or len(bands) == 1 else f"{band:g} nm: "
        notes += [f"{where}{w.message}" for w in caught if issubclass(w.category, FitWarning)]
    return MeasurementFit(Path(path), everything, fitted, keep, selection, results, notes)


# ------------------------------------------------------------------------------ imagery fit
@dataclass(frozen=True)
class SceneFiles:
    """The files of one scene: image, class map and angle source, and how to read them (as for
    :func:`correct_files`; ``scale``/``offset``: the image's, None for the file's)."""

    image: Path
    classes: Path
    angles: Path | str
    angles_kind: str = "geotiff"
    angle_options: Mapping[str, object] = field(default_factory=dict)
    name: str = ""
    align_classes: bool = False
    class_lookup: Mapping[int, int] | None = None
    scale: float | None = None
    offset: float | None = None


@dataclass
class ImageryFit:
    """The result of :func:`fit_class_files`: the fit, the scenes used and those left out."""

    result: ClassFitResult
    scenes: list[SceneFiles]
    wavelengths: np.ndarray | None
    left_out: list[dict[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def table(self) -> ParameterTable:
        return self.result.table

    def report(self) -> dict:
        """JSON-friendly: the classes' fits, scenes left out and warnings."""
        return {
            "source": "imagery", "scenes": len(self.scenes), "scenes_left_out": self.left_out,
            "classes": self.result.report(), "warnings": list(self.warnings),
        }


def _imagery_source(scenes: Sequence[SceneFiles], model: str, class_models: Mapping[int, str] | None) -> str:
    """What an imagery fit used, for the table's ``fit:`` blocks: ``"brdfcorr fit-classes a.tif,
    b.tif (classes a_classes.tif, b_classes.tif; model torrance_sparrow)"``."""
    images = ", ".join(Path(scene.image).name for scene in scenes)
    classes = ", ".join(Path(scene.classes).name for scene in scenes)
    models = f"model {model}" + (
        "; class models " + ", ".join(f"{key}={value}" for key, value in sorted(class_models.items()))
        if class_models else "")
    return f"brdfcorr fit-classes {images} (classes {classes}; {models})"


def fit_class_files(
    scenes: Sequence[SceneFiles], model: str, *, class_models: Mapping[int, str] | None = None,
    names: Mapping[int, str] | None = None, fixed: Mapping[str, float] | None = None,
    max_samples: int = 50_000, seed: int = 0, reflectance_scale: float = 1.0,
    guard: GuardRails = GuardRails(), fallback: str | None = None, chunks: int | None = None,
    wavelengths: Sequence[float] | None = None, skip_unreadable: bool = False,
) -> ImageryFit:
    """Fit per-class, per-band parameters from the pixels of one or many scenes.

    Each scene is opened lazily and checked (:func:`brdfcorr.io.rasters.open_scene`), its stored
    values read as reflectance factors (the file's GDAL scale/offset, or the scene's ``scale`` and
    ``offset``), then the classes' pixels are pooled over the scenes, sampled and fitted
    (:func:`brdfcorr.fit.fit_classes`, with its guard rails). A scene without a given scale whose
    sample does not look like reflectance factors (raw counts) is an :class:`InputError`
    (:func:`brdfcorr.io.rasters.check_reflectance_scale`).

    Parameters
    ----------
    scenes : sequence of SceneFiles
    model, class_models, names, fixed, max_samples, seed, guard, fallback :
        As for :func:`brdfcorr.fit.fit_classes`.
    reflectance_scale : float, default 1
        Kept for callers of brdfcorr 0.1: the scale of every scene's stored values, applied on read
        as a given ``SceneFiles.scale`` (so it replaces a tagged scale, and the file's offset still
        applies); prefer ``SceneFiles.scale``. A scene with a different scale of its own is an
        :class:`InputError`.
    chunks, wavelengths :
        As for :func:`brdfcorr.io.rasters.open_image`.
    skip_unreadable : bool, default False
        Leave out a scene that cannot be opened (listed in ``left_out``) instead of raising; at
        least one scene must open (a chain's fit step uses this).
    """
    opened, used, left_out = [], [], []
    for scene in scenes:
        scale = scene.scale
        if reflectance_scale != 1.0:  # the 0.1 option: the scale of the stored values, now applied on read
            if scale is not None and scale != reflectance_scale:
                raise InputError(f"{scene.image}: scale {scale} and reflectance_scale {reflectance_scale} "
                                 "differ; give the scale once")
            scale = reflectance_scale
        try:
            data = rasters.open_scene(
                scene.image, scene.classes, scene.angles, angles_kind=scene.angles_kind,
                angle_options=dict(scene.angle_options), chunks=chunks, wavelengths=wavelengths,
                scale=scale, offset=scene.offset,
                prepare_classes=class_preparation(scene.align_classes, scene.class_lookup),
            )
            if scale is None:
                rasters.check_reflectance_scale(data.reflectance, str(scene.image))
        except BrdfcorrError as error:
            if not skip_unreadable:
                raise
            left_out.append({"scene": scene.name or str(scene.image), "reason": str(error)})
            continue
        opened.append(data)
        used.append(scene)
    if not opened:
        raise InputError("no scene could be opened for the imagery fit: "
                         + "; ".join(f"{s['scene']}: {s['reason']}" for s in left_out))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ClassFitWarning)
        result = fit_classes(
            [s.reflectance for s in opened], [s.classes for s in opened],
            [xr.Dataset(s.angles) for s in opened], model, class_models=class_models, names=names,
            fixed=fixed, max_samples=max_samples, seed=seed, guard=guard, fallback=fallback,
            source=_imagery_source(used, model, class_models),
        )
    first = opened[0].reflectance
    found = first.coords["wavelength"].values if "wavelength" in first.coords else None
    notes = [str(w.message) for w in caught if issubclass(w.category, ClassFitWarning)]
    return ImageryFit(result, used, found, left_out, notes)
