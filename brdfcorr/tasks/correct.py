"""The correction of one image file (``brdfcorr correct``, a chain's correct step):
:func:`correct_files` runs a :class:`~brdfcorr.tasks.request.CorrectionRequest`.

It reads and writes files but prints nothing: the CLI shows the summary, chains report it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import warnings
from collections.abc import Mapping, Sequence

import dask
import numpy as np
import xarray as xr

from brdfcorr import __version__
from brdfcorr.correction import QA, describe_limits, normalize, normalize_at_nodes, qa_counts, resolve_reference
from brdfcorr.correction.reference import with_hls_sza
from brdfcorr.correction.subgrid import normalize_on_subgrid, suits_subgrid
from brdfcorr.correction.uncertainty import correction_uncertainty
from brdfcorr.defaults import MOSTLY_UNCORRECTED
from brdfcorr.errors import BrdfcorrWarning, InputError, ParameterError
from brdfcorr.io import writer
from brdfcorr.io.angles import RELATIVE_ONLY, window_values
from brdfcorr.io.paths import check_format, check_outputs, raster_files, refuse_existing
from brdfcorr.io.product import ImageFile, gdal_cache_bytes
from brdfcorr.io.scene import SceneData, opened_scene
from brdfcorr.io.wavelengths import parse_wavelength
from brdfcorr.params import ParameterTable, ReferenceGeometry
from brdfcorr.tasks.classmaps import class_preparation, describe_class_map
from brdfcorr.tasks.request import CorrectionRequest, Terrain
from brdfcorr.tasks.results import CorrectionResult, TopographicSummary

__all__ = ["correct_files", "Terrain", "uncorrected_note", "too_few_corrected", "MOSTLY_UNCORRECTED"]


def _merged_qa(qa: xr.DataArray, topographic_qa: xr.DataArray) -> xr.DataArray:
    """The topographic step's flags in the correction's QA layer: ``facing_away`` (self-shadowed),
    ``limited`` and ``topography_uncorrected``; nodata and no class are the BRDF step's own (the
    topographic step writes NaN where it has no value)."""
    passed_on = np.uint8(QA.FACING_AWAY | QA.LIMITED | QA.TOPOGRAPHY_UNCORRECTED)
    return (qa | (topographic_qa & passed_on)).assign_attrs(qa.attrs)


def correct_files(request: CorrectionRequest) -> CorrectionResult:
    """Normalize an image file: read image, angles and class map, write the corrected image.

    Inputs are opened lazily in chunks and checked once (:func:`brdfcorr.io.scene.opened_scene`:
    one grid check, one pass over the angle data that also gives the scene-mean sun zenith),
    normalized with :func:`brdfcorr.normalize` and written tiled and compressed, chunk by chunk, to
    a temporary name renamed when complete, with band descriptions and provenance tags (reference
    geometry, limits, parameter table, brdfcorr version). The QA layer and the uncertainty are
    written in the same pass.

    The image is identified once (its product kind and layout), its chunk size worked out once
    (:func:`brdfcorr.io.product.auto_chunk` unless given) and GDAL's block cache bounded for the
    whole run (:func:`brdfcorr.io.product.gdal_cache_bytes`): the angle and scale checks read
    before the write, and GDAL's default cache (5 % of RAM) would keep their tiles (issue 28); the
    opened scene carries all three (:func:`brdfcorr.io.scene.opened_scene`).

    The image's stored values are read as reflectance factors: scaled with the file's per-band GDAL
    scale and offset (``reflectance = stored * scale + offset``), or with the request's
    ``scene.scale``/``scene.offset``. Without a given scale a sample of the image is checked for raw
    counts (:func:`brdfcorr.io.scale_check.check_reflectance_scale`, a few chunks read, not a pass). The
    output holds reflectance factors (float32, float64 for a float64 input, no GDAL scale/offset)
    and records the scaling applied in the tags ``brdf_input_scale`` and ``brdf_input_offset``;
    with ``outputs.data_type="input"`` an integer input's type instead, with its scale, offset and
    nodata.

    Parameters
    ----------
    request : CorrectionRequest
        The inputs, the table, the reference, the outputs and the engine
        (:mod:`brdfcorr.tasks.request`).

    Returns
    -------
    CorrectionResult
        ``counts``: pixel counts (:func:`brdfcorr.correction.qa_counts`), with an integer output
        (``outputs.data_type="input"``) ``out_of_range`` (the valid pixels stored as nodata and
        flagged ``nodata`` since some band did not fit the type; counted in the writing pass, and
        among ``nodata``); ``reference`` (the geometry used); with a topographic step
        ``topographic`` (its method and the C fit per class and band); where most valid pixels were
        left uncorrected ``notes`` (:func:`uncorrected_note`; also a warning).

    Warns
    -----
    BrdfcorrWarning
        Once per class given as a library ``material`` (a fit at one wavelength) when a band
        centre is more than 100 nm from that wavelength (:meth:`ClassEntry.wavelength_caveat`);
        when fewer than half of the valid pixels were corrected (:func:`uncorrected_note`).

    Raises
    ------
    InputError
        A parameter table without classes; a missing, unreadable or malformed input (named):
        wrong band counts, a float class map,
        angles that look like radians or hold no zenith in [0, 90)
        (:func:`brdfcorr.io.angles.check_angles`; single pixels outside the domain are flagged,
        not an error), an image that holds no reflectance factors after scaling (raw counts without
        a scale), an output that is the same file as an input
        (:class:`brdfcorr.io.paths.InputOverwriteError`).
    GridMismatchError
        A layer not on the image's grid (shape, transform or CRS).
    ParameterError
        The table does not fit the image's bands (names the table, the class and the parameter).
    OutputError
        An existing output without ``overwrite``, an output that is no regular file or the same
        file as the other output, or a failed write (disk full); nothing is left at the output paths.
    """
    request.scene.check_flip(request.flip_view_azimuth)
    _check_outputs(request)
    table, table_path = _load_table(request)
    engine = request.engine
    compute = {"scheduler": engine.scheduler, "num_workers": engine.num_workers}
    with opened_scene(request.scene, chunks=None if engine.chunks is None else int(engine.chunks),
                      prepare_classes=class_preparation(request.align_classes, request.class_lookup),
                      **compute) as scene:
        return _correct(request, scene, table, table_path)


def _refuse_normalized(reflectance: xr.DataArray) -> None:
    """Refuse reflectance that is BRDF-normalized already: a brdfcorr output (its ``brdf_reference``
    tag, which rioxarray reads into the attributes) or an image a reader marked ``brdf_normalized``
    (NEON's bidirectional .002 product: :data:`brdfcorr.io.sensors.neon.NEON_BIDIRECTIONAL`).
    Corrected again with the angle files of its acquisition, its values would carry the factor
    twice, without a word. (In Python, :func:`~brdfcorr.correction.normalize` takes the angles it
    is given: an output normalized again from its reference geometry, the angles set to it, moves
    to another reference.)"""
    source = reflectance.encoding.get("source")
    where = f"image {source}" if source else "reflectance"
    if "brdf_normalized" in reflectance.attrs:
        raise InputError(f"{where} is BRDF-normalized already: {reflectance.attrs['brdf_normalized']}")
    if "brdf_reference" in reflectance.attrs:
        raise InputError(f"{where} is a brdfcorr output, normalized already to {reflectance.attrs['brdf_reference']}; "
                         "correct the image it was made from")


def _correct(request: CorrectionRequest, scene: SceneData, table: ParameterTable,
             table_path: str | None) -> CorrectionResult:
    """:func:`correct_files` of a scene opened for the run (:func:`brdfcorr.io.scene.opened_scene`)."""
    _refuse_normalized(scene.reflectance)
    engine = request.engine
    _warn_wavelength_caveats(table, scene.reflectance)
    reference, sza_source = _scene_reference(request.reference, table, scene)
    corrected, qa, sigma, topographic = _corrected_layers(request, scene, table, reference)
    if topographic is not None:
        qa = _merged_qa(qa, topographic.qa)
    corrected, qa, encoding = _as_output(corrected, qa, scene, request)
    files = request.outputs
    targets = {path: layer for path, layer in ((files.corrected, corrected), (files.qa, qa), (files.uncertainty, sigma))
               if path is not None}
    commit_tags = _fingerprint_tags(files.fingerprint)  # the corrected output's only
    envi, scene_tags = _envi_outputs(request, scene), _scene_tags(scene, request.class_lookup)
    tags = {
        "brdf_reference": reference.describe(),
        "brdf_reference_sza_source": sza_source,
        "brdf_limits": describe_limits(request.limits),
        "brdf_parameter_table": table_path or "(in memory)",
        "brdf_parameter_table_content": json.dumps(table.to_dict(), separators=(",", ":")),
        **scene_tags,
    }
    geotiff = writer.GeoTiffOutput(compress=files.compress, blocksize=scene.chunks, cog=files.cog)
    with writer.writing(targets, geotiff, tags=tags, commit_tags=commit_tags, callbacks=engine.callbacks, envi=envi,
                        scheduler=engine.scheduler,
                        gdal_cache=scene.cache or gdal_cache_bytes(request.scene.image, scene.chunks)) as writes:
        # The one pass: the correction's chunks computed here, each stored by the writer as it comes.
        *_, counts = dask.compute(*writes, {**qa_counts(qa), **encoding},
                                  scheduler=writer.local_scheduler(engine.scheduler),
                                  num_workers=scene.threads)
    pixels = {key: int(value) for key, value in counts.items()}
    notes = [note for note in (uncorrected_note(pixels), _uncertainty_note(files.uncertainty, table)) if note]
    for note in notes:
        warnings.warn(note, BrdfcorrWarning, stacklevel=2)
    summary = None
    if topographic is not None:
        c_table = topographic.c_table
        summary = TopographicSummary(request.terrain.topographic,  # type: ignore[union-attr]
                                     () if c_table is None else tuple(c_table.to_dict(orient="records")))
    return CorrectionResult(pixels, reference, notes=tuple(notes), topographic=summary)


def _uncertainty_note(output, table: ParameterTable) -> str | None:
    """A note when an uncertainty output was written and classes of the table have no errors to
    propagate (their pixels are NaN there); else None."""
    bare = table.classes_without_errors() if output is not None else []
    if not bare:
        return None
    return (f"{', '.join(bare[:5])}{' ...' if len(bare) > 5 else ''} have no fit: block (covariance) in the parameter "
            f"table: their pixels are NaN in the uncertainty output {output}")


def _check_outputs(request: CorrectionRequest) -> None:
    """The output guard, formats and extensions, and existing outputs (``overwrite``)."""
    files, inputs = request.outputs, request.inputs
    outputs = {"output": files.corrected, "QA output": files.qa, "uncertainty output": files.uncertainty}
    if files.format == "ENVI":  # its header and .aux.xml: never an input's (image.img and image.bsq share image.hdr)
        header, aux = (final for _, final in writer.envi_sidecars(files.corrected, files.corrected))
        outputs.update({f"output header {header}": header, f"output sidecar {aux}": aux})
    check_outputs(outputs, inputs)  # the inputs' sidecars (ENVI headers in both namings, .aux.xml) included
    check_format(files.corrected, files.format)
    for path, what in ((files.qa, "QA output"), (files.uncertainty, "uncertainty output")):
        if path is not None:
            check_format(path, "GTiff", what)
    if not files.overwrite:
        refuse_existing([*raster_files(files.corrected, envi=files.format == "ENVI"), *raster_files(files.qa),
                         *raster_files(files.uncertainty)])


def _load_table(request: CorrectionRequest) -> tuple[ParameterTable, str | None]:
    """The parameter table and where it came from (for the provenance tag and messages); a table
    without classes, which would write an unchanged copy, or a table of other classes than 1 without
    a class map (the whole image is class 1), is an InputError."""
    if isinstance(request.table, ParameterTable):
        table, source = request.table, request.table_source
    else:
        table, source = ParameterTable.load(request.table), str(request.table)
    if not table.classes:
        raise InputError(f"{source or 'parameter table'}: the parameter table has no classes: nothing would be "
                         "corrected")
    ids = sorted(entry.id for entry in table.classes)
    if request.scene.classes is None and ids != [1]:  # the whole image is class 1: only a one-class table fits
        raise InputError(f"{source or 'parameter table'}: classes {ids}, but no class map was given (the whole "
                         "image would be class 1); give the class map (--classes)")
    return table, source


def too_few_corrected(counts: Mapping[str, int], share: float = MOSTLY_UNCORRECTED) -> bool:
    """Whether the correction touched less than ``share`` of the valid pixels: QA ``corrected`` over
    ``corrected + no_class + unknown_class`` (nodata is not counted). No valid pixel at all is too
    few for any ``share`` above 0: an image of nodata only (NaN, fill, angles without a value)
    came out as it went in."""
    valid = sum(int(counts.get(key, 0)) for key in ("corrected", "no_class", "unknown_class"))
    return counts.get("corrected", 0) < share * valid if valid else share > 0


def uncorrected_note(counts: dict[str, int]) -> str | None:
    """A note when most valid pixels (not nodata) were left uncorrected, naming why, or when no
    pixel was valid; else None."""
    if not too_few_corrected(counts):
        return None
    valid = counts["corrected"] + counts["no_class"] + counts["unknown_class"]
    if not valid:
        return (f"no pixel was corrected: all {counts.get('nodata', 0)} pixels are nodata (the image, an angle or "
                "the surface without a valid value); check the inputs' nodata")
    return (f"only {100 * counts['corrected'] / valid:.0f} % of the {valid} valid pixels were corrected: "
            f"{counts['no_class']} have no class and {counts['unknown_class']} a class the parameter table does "
            "not have; check the class map against the table's class ids")


def _scene_reference(reference, table: ParameterTable, scene: SceneData) -> tuple[ReferenceGeometry, str]:
    """The reference geometry, a ``"mean"`` sun zenith replaced by the scene's mean (``"hls"`` by
    HLS v1.4's at the scene centre's latitude), and how its sun zenith was chosen: ``"fixed"``,
    ``"mean"``, ``"hls"`` or ``"observed"``."""
    resolved = resolve_reference(reference, table)
    if resolved.sza == "hls":
        return with_hls_sza(resolved, scene.reflectance), "hls"
    if resolved.sza != "mean":
        return resolved, resolved.sza if isinstance(resolved.sza, str) else "fixed"
    mean = scene.statistics.means["sza"]
    if not np.isfinite(mean):
        where = scene.angles["sza"].encoding.get("source", "sza")
        raise InputError(f"{where}: no valid solar zenith for the scene mean")
    return resolved.model_copy(update={"sza": float(mean)}), "mean"


def _corrected_layers(request: CorrectionRequest, scene: SceneData, table: ParameterTable,
                      reference: ReferenceGeometry):
    """The corrected reflectance, its QA flags and 1-sigma (or None), and the topographic step's
    result (or None), all lazy."""
    if request.factor_at == "nodes":
        with _table_named(request):
            return (*_corrected_at_nodes(request, scene, table, reference), None, None)
    reflectance, surface, topographic = scene.reflectance, {}, None
    if request.terrain is not None:
        compute = {"scheduler": request.engine.scheduler, "num_workers": request.engine.num_workers}
        reflectance, surface, topographic = request.terrain.apply(scene, scene.chunks, request.limits, compute)
    if (request.terrain is None and request.scene.classes is None and request.outputs.uncertainty is None
            and suits_subgrid(reflectance, scene.angles, table)):  # the per-pixel factor, sampled (correction.subgrid)
        with _table_named(request):
            corrected, qa = normalize_on_subgrid(reflectance, scene.angles, table, reference, limits=request.limits,
                                                 extrapolate=request.extrapolate,
                                                 flip_view_azimuth=request.flip_view_azimuth)
        return corrected, qa, None, None
    arguments = dict(
        reflectance=reflectance, classes=scene.classes, angles={**scene.angles, **surface}, params=table,
        reference=reference, limits=request.limits, extrapolate=request.extrapolate,
        flip_view_azimuth=request.flip_view_azimuth,
    )
    with _table_named(request):
        corrected, qa = normalize(**arguments, unknown=request.unknown)
        sigma = correction_uncertainty(**arguments) if request.outputs.uncertainty is not None else None
    if sigma is not None:
        sigma = sigma.drop_vars("wavelength", errors="ignore").rio.write_nodata(np.nan, encoded=True)
        sigma.attrs["long_name"] = _band_descriptions(scene.reflectance)
    return corrected, qa, sigma, topographic


def _corrected_at_nodes(request: CorrectionRequest, scene: SceneData, table: ParameterTable,
                        reference: ReferenceGeometry):
    """The corrected reflectance and its QA flags with the factor at the angle grid's nodes
    (:mod:`brdfcorr.correction.nodes`), for what that method suits: one class over the whole image."""
    # Without a class map the table holds class 1 alone (_load_table): one class for every pixel.
    unsuited = [what for what, given in (("a class map", request.scene.classes is not None),
                                         ("terrain", request.terrain is not None),
                                         ("an uncertainty output", request.outputs.uncertainty is not None))
                if given]
    if unsuited:
        raise InputError(f"cannot evaluate the factor at the angle grid's nodes with {', '.join(unsuited)}: it is "
                         "one smooth correction of the whole image (evaluate it at the pixels)")
    return normalize_at_nodes(scene.reflectance, scene.angles, table, reference, limits=request.limits,
                              extrapolate=request.extrapolate, flip_view_azimuth=request.flip_view_azimuth)


@contextlib.contextmanager
def _table_named(request: CorrectionRequest):
    """A ParameterError of the correction (the table does not fit the image's bands, whichever way
    the factor is evaluated) raised naming the table and the image."""
    try:
        yield
    except ParameterError as error:
        table_path = request.table_source if isinstance(request.table, ParameterTable) else request.table
        image = request.scene.image_label
        raise ParameterError(f"{table_path or 'parameter table'}: {error} (image {image})") from None


def _as_output(corrected: xr.DataArray, qa: xr.DataArray, scene: SceneData, request: CorrectionRequest):
    """The corrected layer as it is written (physical values or the input's integers, band
    descriptions, no input scaling or ENVI header fields), the QA layer with values that do
    not fit an integer output flagged ``nodata``, and the lazy counts of the encoding for the
    writing pass (``out_of_range`` for an integer output; none for floats). The integers are
    encoded chunk by chunk as the write consumes them (:func:`brdfcorr.io.writer.encode_integers`):
    the correction is computed once."""
    corrected = corrected.drop_vars("wavelength", errors="ignore").rio.write_nodata(np.nan, encoded=True)
    corrected.attrs["long_name"] = _band_descriptions(scene.reflectance)
    for name in ("scale_factor", "add_offset"):  # the output holds physical values
        corrected.attrs.pop(name, None)
    for name in _envi_header_items(scene.image, corrected.attrs):  # no tags of the output
        corrected.attrs.pop(name)
    stored = np.dtype(scene.reflectance.encoding.get("rasterio_dtype", scene.reflectance.dtype))
    if request.outputs.data_type == "input" and stored.kind in "iu":
        if stored.itemsize > 4:
            raise InputError(
                f"output type 'input' (--output-type input): image {request.scene.image_label} is stored as {stored}, "
                "and a 64-bit integer output cannot be written exactly (GDAL keeps its nodata as a double: "
                "int64's lowest and uint64's highest value do not read back); write floats (--output-type float)"
            )
        attrs = scene.reflectance.attrs
        corrected, out_of_range = writer.encode_integers(
            corrected, stored, attrs["brdf_input_scale"], attrs["brdf_input_offset"],
            scene.reflectance.encoding.get("_FillValue"),
        )
        qa = (qa | xr.where(out_of_range, QA.NODATA, 0).astype(np.uint8)).assign_attrs(qa.attrs)
        return corrected, qa, {"out_of_range": out_of_range.sum().data}
    return corrected, qa, {}


def _envi_outputs(request: CorrectionRequest, scene: SceneData) -> dict:
    """The ENVI header contents of an ENVI output (none for a GeoTIFF)."""
    if request.outputs.format != "ENVI":
        return {}
    coords = scene.reflectance.coords
    bad = None if scene.image is None else scene.image.bad_bands
    return {request.outputs.corrected: writer.EnviOutput(
        interleave=request.outputs.interleave,
        wavelength=coords["wavelength"].values.tolist() if "wavelength" in coords else None,
        fwhm=np.asarray(coords["fwhm"].values).tolist() if "fwhm" in coords else None,
        bad_bands=None if bad is None else bad.tolist(),
    )}


def _fingerprint_tags(fingerprint: str | None) -> dict[str, str]:
    """The tags a resumed chain compares (:mod:`brdfcorr.chain.resume`), written to the corrected
    output only, which is renamed into place after the QA and uncertainty outputs: whoever finds
    them finds every output of the correction complete."""
    if fingerprint is None:
        return {}
    return {"brdf_fingerprint": hashlib.sha256(fingerprint.encode()).hexdigest(),
            "brdf_fingerprint_content": fingerprint}


def _scene_tags(scene: SceneData, class_lookup) -> dict[str, str]:
    """The output's tags that describe the scene: input scaling, class map, wavelengths."""
    tags = {
        "brdf_input_scale": _describe_scaling(scene.reflectance.attrs["brdf_input_scale"]),
        "brdf_input_offset": _describe_scaling(scene.reflectance.attrs["brdf_input_offset"]),
        "brdfcorr_version": __version__,
    }
    class_map_note = describe_class_map(scene.classes, class_lookup)
    if class_map_note:
        tags["brdf_class_map"] = class_map_note
    coords = scene.reflectance.coords
    if "wavelength" in coords:
        tags.update(writer.wavelength_tags(coords["wavelength"].values,
                                           coords["fwhm"].values if "fwhm" in coords else None))
    sun = _centre_sun(scene.angles)
    if sun is not None:
        tags["brdf_scene_sun"] = f"zenith {sun[0]:.1f}, azimuth {sun[1]:.1f} (scene centre, deg)"
    return tags


def _centre_sun(angles: Mapping[str, xr.DataArray], half: int = 16) -> tuple[float, float] | None:
    """The sun zenith and azimuth [deg] at the scene centre (the mean of a window of up to
    2 ``half`` pixels a side; the azimuth a circular mean), for figures that show where the sun
    was; None where the source gives the relative azimuth only or the window holds no value."""
    if angles["saa"].attrs.get(RELATIVE_ONLY):
        return None
    ny, nx = angles["sza"].sizes["y"], angles["sza"].sizes["x"]
    rows = slice(max(ny // 2 - half, 0), min(ny // 2 + half, ny))
    cols = slice(max(nx // 2 - half, 0), min(nx // 2 + half, nx))
    zenith = window_values(angles["sza"], rows, cols)  # from the coarse grid where there is one
    azimuth = np.radians(window_values(angles["saa"], rows, cols))
    valid = np.isfinite(zenith) & np.isfinite(azimuth)
    if not valid.any():
        return None
    mean_azimuth = np.degrees(np.arctan2(np.sin(azimuth[valid]).mean(), np.cos(azimuth[valid]).mean())) % 360.0
    return float(zenith[valid].mean()), float(mean_azimuth)


def _warn_wavelength_caveats(table: ParameterTable, reflectance: xr.DataArray) -> None:
    """A :class:`BrdfcorrWarning` per class whose single-wavelength fit (a library material) is
    applied to far-away bands (:meth:`brdfcorr.params.ClassEntry.wavelength_caveat`)."""
    if "wavelength" not in reflectance.coords:  # band centres unknown: nothing to compare
        return
    for entry in table.classes:
        caveat = entry.wavelength_caveat(reflectance["wavelength"].values)
        if caveat is not None:
            warnings.warn(caveat, BrdfcorrWarning, stacklevel=3)


def _envi_header_items(image: ImageFile | None, attrs: Mapping) -> list[str]:
    """The attrs that rioxarray took from an ENVI input's header (its ENVI metadata domain, known
    from the image's identification, and the ``Band_N`` band names and ``wavelength_units`` GDAL
    mirrors into the default domain): header fields of the input, not provenance of the output.
    None for another format."""
    if image is None or image.envi_header is None:
        return []
    header = set(image.envi_header) | {"wavelength", "wavelength_units", "fwhm"}
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
    if isinstance(described, str) and n_bands == 1:  # rioxarray gives one band's description as a string
        described = (described,)
    wavelengths = reflectance["wavelength"].values if "wavelength" in reflectance.coords else None
    if isinstance(described, (tuple, list)) and len(described) == n_bands and all(described):
        # a description naming another centre than the band's (--wavelengths given) gives the band's
        return tuple(f"{writer.wavelength_text(centre)} nm" if _names_another_centre(str(text), centre) else str(text)
                     for text, centre in zip(described, [None] * n_bands if wavelengths is None else wavelengths))
    if wavelengths is not None:
        return tuple(f"{writer.wavelength_text(centre)} nm" for centre in wavelengths)
    return tuple(f"band {number}" for number in range(1, n_bands + 1))


def _names_another_centre(description: str, centre: float | None) -> bool:
    """Whether a band description names a wavelength other than the band's ``centre`` [nm]."""
    named = parse_wavelength(description)
    return named is not None and centre is not None and not np.isclose(named, centre, rtol=0, atol=0.05)


