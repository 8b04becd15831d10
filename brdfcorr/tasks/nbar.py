"""NBAR of a whole product folder in one call (``brdfcorr nbar``): :func:`nbar_files`.

Nadir BRDF-adjusted reflectance with the fixed-coefficient c-factor method of Roy et al. (2016,
2017), as HLS and sen2nbar compute it: every pixel is one class whose RTLSR weights are the
published global ones of its band (:mod:`brdfcorr.models.coefficients`), and

    NBAR = rho_observed * f(sza_ref, 0, 0) / f(sza, vza, raa)          (Roy et al. 2016, eq. 7)

with the reference geometry of HLS (nadir view; sun zenith the scene mean by default, or a value
or each pixel's own). The folder's bands are stacked on one grid and masked
(:func:`brdfcorr.io.sensors.folders.write_stack`, a temporary virtual raster beside the output that
reads the product's files), then corrected by :func:`brdfcorr.tasks.correct.correct_files`
like any image; with ``view_band="each"`` band by band, each with its own view angles. An HLS
granule, NBAR already, is only moved to a fixed reference sun zenith (:mod:`brdfcorr.tasks.hls`).
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np
import rasterio
import rioxarray
import xarray as xr

from brdfcorr.correction import qa_counts
from brdfcorr.errors import InputError, OutputError, SensorInputError
from brdfcorr.io.paths import check_outputs, raster_files, refuse_existing
from brdfcorr.io.scene import SceneSources
from brdfcorr.io.sensors.folders import ProductFolder, band_stacks, find_product, write_stack
from brdfcorr.io.sensors.hls import HlsGranule, find_hls_granule, hls_refusal
from brdfcorr.io.sensors.stac import find_stac_item, is_stac_item
from brdfcorr.io.writer import GeoTiffOutput, wavelength_tags, write_rasters
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable, ReferenceGeometry
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.hls import hls_sun_zenith_layers
from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles
from brdfcorr.tasks.results import NbarResult

__all__ = ["nbar_files", "nbar_table", "NbarMethod", "EACH_BAND", "NBAR_CHUNK", "remove_stale_scratch"]

#: ``view_band`` (``--view-band``) value that corrects each Sentinel-2 band with its own view grids.
EACH_BAND = "each"
#: Default chunk and output tile size [pixels]: a 1024 x 1024 window is then four chunks that the
#: threads share (one 1024 chunk left a core idle: 0.78 s against 0.68 s for the benchmark's two
#: runs on 2 cores, benchmarks/bench_sen2nbar.py); a full tile is 22 x 22 chunks. The numbers do not
#: depend on the chunks (pixel by pixel computations).
NBAR_CHUNK = 512


@dataclass(frozen=True)
class NbarMethod:
    """How the NBAR is computed.

    Attributes
    ----------
    coefficients : {"roy2017", "roy2016"}
        The coefficient set; roy2016 has no red-edge weights (pick ``bands`` without B05-B07).
    reference_sza : float or {"mean", "observed", "hls"}
        Reference sun zenith [deg]: a value, the scene mean, each pixel's own (sen2nbar), or HLS
        v1.4's for the scene centre's latitude (:func:`brdfcorr.correction.reference.hls_sza`).
    view_band : str, optional
        Sentinel-2: this band's view grids (``"B04"``) for every band, or ``"each"``
        (:data:`EACH_BAND`): every band its own, as sen2nbar (one correction per band). Default:
        the mean of all bands' grids (they differ by up to about 0.5 deg: up to 0.3 % in a c-factor).
    factor_at : {"pixels", "nodes"}
        Sentinel-2: the c-factor at every pixel from the angles interpolated to it (default), or at
        the 5 km nodes of the angle grids, interpolated to the pixels (sen2nbar's method, faster;
        within 0.004 % of the pixels' on a real tile, :mod:`brdfcorr.correction.nodes`).
    """

    coefficients: str = "roy2017"
    reference_sza: float | str = "mean"
    view_band: str | None = None
    factor_at: Literal["pixels", "nodes"] = "pixels"


def nbar_table(product: ProductFolder, coefficients: str = "roy2017") -> ParameterTable:
    """The one-class table (id 1) of the product's bands from the built-in coefficient set
    ``coefficients``: each band's weights (divided by pi: sr^-1) at its centre [nm] (the class's
    ``wavelengths``, ascending).

    The table carries the bands' identities as wavelengths, so it is matched to an image by the
    image's band centres (its ``wavelength`` coordinate or tag, :mod:`brdfcorr.params.bands`), as
    every table with wavelengths is, not by position: a cube of the product's bands in another
    order, or some of them, takes each band's own weights (a band centre between the product's is
    interpolated, one outside them refused without ``extrapolate``; an image without band centres
    is refused, naming how to give them).
    """
    library = load_coefficients(coefficients)
    bands = sorted(zip(product.wavelengths, product.bands, strict=True))  # (centre [nm], name), ascending
    entry = library.table_entry(1, sensor=product.sensor, bands=[name for _, name in bands],
                                name=f"{library.name} ({product.sensor})")
    return ParameterTable(classes=[ClassEntry(**entry, wavelengths=[centre for centre, _ in bands])])


def nbar_files(product: str | os.PathLike, outputs: OutputFiles, *, resolution: int | None = None,
               bands: Sequence[str] | None = None, masked: Sequence[int] | None = None,
               method: NbarMethod = NbarMethod(), keep_stack: str | os.PathLike | None = None,
               engine: Engine = Engine()) -> NbarResult:
    """NBAR of a Sentinel-2 L2A SAFE folder or a Landsat Collection-2 L2 folder; an HLS v2.0
    granule moved to a fixed reference sun zenith.

    Parameters
    ----------
    product : path-like
        The product folder (:func:`brdfcorr.io.sensors.folders.find_product`,
        :func:`brdfcorr.io.sensors.hls.find_hls_granule`).
    outputs : OutputFiles
        The NBAR GeoTIFF (float32 reflectance factors, bands named in the product's order), QA
        flags; ``overwrite`` as for ``correct``.
    resolution : {10, 20}, optional
        Sentinel-2 output pixel size [m] (default 20); Landsat: 30.
    bands : sequence of str, optional
        Band names (``B04``, ``SR_B4``) in output order (default: every band with coefficients).
    masked : sequence of int, optional
        SCL classes or QA_PIXEL bits made no data (default: clouds, shadows; ``()``: fill only).
    method : NbarMethod
        Coefficients, reference sun zenith, view grids, where the factor is evaluated.
    keep_stack : path-like, optional
        Keep the uncorrected, masked, scaled bands here: a GDAL virtual raster (``.vrt``) reading
        the product's files by absolute path (and ``<name>_mask.tif``), e.g. BEFORE of ``assess``.
    engine : Engine
        Chunks (default :data:`NBAR_CHUNK`), scheduler, progress.

    Returns
    -------
    NbarResult
        The pixel counts and reference geometry (:func:`~brdfcorr.tasks.correct.correct_files`), the ``product``.

    Raises
    ------
    SensorInputError
        Not a product folder, an HLS granule without a fixed reference sun zenith (NBAR already), or a
        file missing (named).
    OutputError
        An existing output without ``overwrite``; a kept stack not named ``.vrt``.
    """
    refuse_archive(product)
    granule = find_hls_granule(product, bands=bands)
    if granule is not None:  # NBAR already: at most moved to another sun zenith
        _refuse_for_hls(product, granule, resolution, method, keep_stack)
        return _moved_hls(granule, outputs, masked, method, engine)
    folder = find_product_or_item(product, resolution=resolution, bands=bands, masked=masked)
    angle_options = _angle_options(folder, method.view_band)
    _check_outputs(outputs, folder, keep_stack)
    engine = replace(engine, chunks=engine.chunks or NBAR_CHUNK)
    with _scratch(outputs) as scratch:
        stack = write_stack(folder, keep_stack or Path(scratch) / "stack.vrt", chunks=engine.chunks)
        if method.view_band == EACH_BAND:
            counts, reference = _band_by_band(folder, stack, Path(scratch), outputs, method, engine)
        else:
            counts, reference = _one_stack(folder, stack, angle_options, outputs, method, engine)
    return NbarResult(counts, reference, folder)


def find_product_or_item(product: str | os.PathLike, *, resolution: int | None = None,
                         bands: Sequence[str] | None = None, masked: Sequence[int] | None = None) -> ProductFolder:
    """The product of a folder (:func:`~brdfcorr.io.sensors.folders.find_product`) or of a
    Sentinel-2 STAC item file with local assets (:func:`~brdfcorr.io.sensors.stac.find_stac_item`)."""
    if is_stac_item(product):
        return find_stac_item(product, resolution=resolution or 20, bands=bands, masked=masked)
    return find_product(product, resolution=resolution, bands=bands, masked=masked)


def _one_stack(folder: ProductFolder, stack: Path, angle_options: dict, outputs: OutputFiles, method: NbarMethod,
               engine: Engine) -> tuple[Mapping[str, int], ReferenceGeometry]:
    """The bands corrected together with one set of view angle grids (one :func:`correct_files` of
    the stack): the pixel counts and the reference geometry."""
    result = correct_files(_request(folder, SceneSources(stack, None, folder.angles), angle_options,
                                    nbar_table(folder, method.coefficients), replace(outputs, fingerprint=None),
                                    method, engine))
    return result.counts, result.reference


def _refuse_for_hls(product, granule: HlsGranule, resolution: int | None, method: NbarMethod, keep_stack) -> None:
    """The settings an HLS granule (NBAR already, at 30 m) cannot take, as one error: those of the
    Sentinel-2 and Landsat folders, and a reference sun zenith that is not a fixed angle."""
    if (method.view_band is not None or method.factor_at != "pixels" or keep_stack is not None
            or resolution not in (None, 30)):
        raise InputError(f"{product}: an HLS granule is NBAR already, at 30 m; resolution (--resolution), "
                         "view_band (--view-band), factor_at (--factor-at) and keep_stack (--keep-stack) are "
                         "for Sentinel-2 and Landsat folders")
    if method.reference_sza in ("mean", "observed"):
        raise SensorInputError(hls_refusal(granule))


def _moved_hls(granule: HlsGranule, outputs: OutputFiles, masked: Sequence[int] | None, method: NbarMethod,
               engine: Engine) -> NbarResult:
    """An HLS granule moved to the method's fixed reference sun zenith [deg]
    (:func:`brdfcorr.tasks.hls.hls_sun_zenith_layers`), written as :func:`nbar_files` writes."""
    _check_outputs(outputs, granule, None)
    corrected, qa, tags, reference = hls_sun_zenith_layers(
        granule, coefficients=method.coefficients, reference_sza=method.reference_sza, masked=masked,
        engine=replace(engine, chunks=engine.chunks or NBAR_CHUNK))
    return NbarResult(_write_bands(corrected, qa, tuple(granule.bands), outputs, tags, engine), reference, granule)


#: Archive suffixes products are downloaded as (Copernicus: ``….SAFE.zip``; USGS: ``….tar``).
ARCHIVE_SUFFIXES = (".zip", ".tar", ".tar.gz", ".tgz")


def refuse_archive(product: str | os.PathLike) -> None:
    """An :class:`~brdfcorr.errors.InputError` for a product still in its download archive: the
    readers take the unpacked folder, and the archive's name says which one to make."""
    path = Path(product)
    suffix = next((s for s in ARCHIVE_SUFFIXES if path.name.lower().endswith(s)), None)
    if suffix is not None and path.is_file():
        folder = path.with_name(path.name[: -len(suffix)])
        tool = "unzip" if suffix == ".zip" else "tar -xf"
        raise InputError(f"{path} is an archive; brdfcorr reads the unpacked product folder: unpack it "
                         f"({tool} {path.name}) and give {folder.name}")


def _request(folder: ProductFolder, scene: SceneSources, angle_options: dict, table: ParameterTable,
             outputs: OutputFiles, method: NbarMethod, engine: Engine) -> CorrectionRequest:
    """The correction of ``scene`` (a stack of the folder's bands) with the product's angles. The
    product's scaling, where one for every band, is given, so no chunk is read to check it."""
    scales, offsets = set(folder.scales), set(folder.offsets)
    known = {"scale": scales.pop(), "offset": offsets.pop()} if len(scales) == len(offsets) == 1 else {}
    scene = replace(scene, angles_kind=folder.angles_kind, angle_options=angle_options, **known)
    return CorrectionRequest(scene, table, outputs, reference={"sza": method.reference_sza, "vza": 0.0, "raa": 0.0},
                             engine=engine, table_source=f"built-in coefficients {method.coefficients}",
                             reads=folder.files, factor_at=method.factor_at)


#: A scratch folder's name: ``.nbar-<process id>-<random>`` (:func:`_scratch`).
_SCRATCH = re.compile(r"\.nbar-(\d+)-\w+")


def _scratch(outputs: OutputFiles) -> tempfile.TemporaryDirectory:
    """A temporary folder beside the output (on its file system) for the band stack, named with
    this process's id; the folders a killed process left there (SIGKILL, a power cut: no cleanup
    ran) are removed first (:func:`remove_stale_scratch`)."""
    folder = Path(outputs.corrected).parent
    remove_stale_scratch(folder)
    try:
        return tempfile.TemporaryDirectory(prefix=f".nbar-{os.getpid()}-", dir=folder)
    except OSError as error:
        raise OutputError(f"cannot write the band stack beside output {outputs.corrected}: {error.strerror}") from None


def remove_stale_scratch(folder: Path) -> list[Path]:
    """Remove the scratch folders (``.nbar-<pid>-...``) in ``folder`` whose process is gone; those of
    running processes (another ``nbar`` writing beside its output here) stay. Returns the removed."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            match = _SCRATCH.fullmatch(entry.name)
            if match and entry.is_dir(follow_symlinks=False) and not _alive(int(match.group(1))):
                shutil.rmtree(entry.path, ignore_errors=True)
                removed.append(Path(entry.path))
    return removed


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs (one of another user counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return pid > 0
    return True


def _band_by_band(folder: ProductFolder, stack: Path, scratch: Path, outputs: OutputFiles, method: NbarMethod,
                  engine: Engine) -> tuple[dict[str, int], ReferenceGeometry]:
    """Each band corrected with its own view angle grids (one :func:`correct_files` per band into
    uncompressed files in ``scratch``), then written as one output: the bands in order, the QA
    flags of every band combined (a flag of any band is the pixel's); the counts of those and the
    reference geometry."""
    parts, reference = [], None
    for index, (name, band_stack) in enumerate(zip(folder.bands, band_stacks(stack, scratch))):
        one = replace(folder, bands={name: folder.bands[name]}, wavelengths=folder.wavelengths[index:index + 1],
                      scales=folder.scales[index:index + 1], offsets=folder.offsets[index:index + 1])
        part = OutputFiles(scratch / f"nbar_{name}.tif", qa=scratch / f"qa_{name}.tif", compress="none")
        reference = correct_files(_request(one, SceneSources(band_stack, None, folder.angles),
                                           {**folder.angle_options, "band": name},
                                           nbar_table(one, method.coefficients), part, method, engine)).reference
        parts.append(part)
    chunks = {"y": engine.chunks, "x": engine.chunks}
    corrected = xr.concat([rioxarray.open_rasterio(part.corrected, chunks=chunks, masked=True) for part in parts],
                          dim="band").assign_coords(band=np.arange(1, len(parts) + 1))
    flags = [rioxarray.open_rasterio(part.qa, chunks=chunks).isel(band=0, drop=True) for part in parts]
    qa = functools.reduce(np.bitwise_or, flags).rio.write_nodata(None)
    with rasterio.open(parts[0].corrected) as first:
        tags = first.tags()
    tags.update(wavelength_tags(folder.wavelengths),
                brdf_parameter_table_content=json.dumps(nbar_table(folder, method.coefficients).to_dict(),
                                                        separators=(",", ":")),
                brdf_view_angles="each band its own view angle grids")
    return _write_bands(corrected, qa, tuple(folder.bands), outputs, tags, engine), reference


def _write_bands(corrected: xr.DataArray, qa: xr.DataArray, names: tuple[str, ...], outputs: OutputFiles,
                 tags: dict, engine: Engine) -> dict[str, int]:
    """Write the corrected bands (described by ``names``) and, if asked, their QA flags in one pass
    (:func:`brdfcorr.io.writer.write_rasters`); the counts of the flags."""
    corrected.attrs, qa.attrs = {"long_name": names}, {**qa.attrs, "long_name": ("qa",)}
    targets = {outputs.corrected: corrected.rio.write_nodata(np.nan, encoded=True)}
    if outputs.qa is not None:
        targets[outputs.qa] = qa
    counts = write_rasters(targets, geotiff=GeoTiffOutput(compress=outputs.compress,
                                                          blocksize=engine.chunks or NBAR_CHUNK, cog=outputs.cog),
                           tags=tags, compute_with=qa_counts(qa), callbacks=engine.callbacks,
                           scheduler=engine.scheduler, num_workers=engine.num_workers)
    return {key: int(value) for key, value in counts.items()}


def _angle_options(folder: ProductFolder, view_band: str | None) -> dict:
    """The angle reader's options: the folder's, with a Sentinel-2 band's view grids if asked."""
    options = dict(folder.angle_options)
    if view_band is not None:
        if folder.angles_kind != "sentinel2":
            raise InputError(f"{folder.path}: view_band (--view-band) is for Sentinel-2 products")
        if view_band != EACH_BAND:
            options["band"] = view_band
    return options


def _check_outputs(outputs: OutputFiles, folder: ProductFolder | HlsGranule, keep_stack) -> None:
    """Before anything is stacked: outputs that are no product file, in an existing folder, and
    (without ``overwrite``) not there yet; a kept stack named ``.vrt``."""
    kept = {}
    if keep_stack is not None:
        if Path(keep_stack).suffix.lower() != ".vrt":
            raise OutputError(f"the kept band stack {keep_stack} is a virtual raster: name it .vrt")
        kept = {"kept band stack": keep_stack,
                "kept stack's mask": Path(keep_stack).with_name(f"{Path(keep_stack).stem}_mask.tif")}
    check_outputs({"output": outputs.corrected, "QA output": outputs.qa, **kept}, folder.files)
    if not outputs.overwrite:
        refuse_existing([*raster_files(outputs.corrected), *raster_files(outputs.qa), *kept.values()])
    if not Path(outputs.corrected).parent.is_dir():
        raise OutputError(f"output folder {Path(outputs.corrected).parent} does not exist")
