"""One scene's input files, opened lazily and checked together: where they are
(:class:`SceneSources`) and what they hold (:class:`SceneData`, :func:`open_scene`; for a whole
run, with the image identified once and GDAL's cache bounded: :func:`opened_scene`)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import rasterio
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import BrdfcorrError, GridMismatchError, InputError
from brdfcorr.io import scale_check
from brdfcorr.io.angles import ANGLE_NAMES, AngleStatistics, check_angles, open_angles
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.paths import PathLike
from brdfcorr.io.product import ImageFile, auto_chunk, gdal_cache_bytes, identify_image
from brdfcorr.io.rasters import open_classes, open_image
from brdfcorr.io.sensors import flip_refusal
from brdfcorr.io.writer import pass_threads

__all__ = ["SceneSources", "SceneData", "open_scene", "opened_scene", "check_class_grid"]


@dataclass(frozen=True)
class SceneSources:
    """Where one scene's reflectance, class map and sun/view angles come from.

    Attributes
    ----------
    image, classes : path-like
        Reflectance raster and class map; ``classes=None``: one class, id 1, for the whole image
        (a table with one class, e.g. the built-in coefficients of :mod:`brdfcorr.models.coefficients`).
    angles : path-like or str, optional
        The angle source: a 4-band raster (sza, saa, vza, vaa [deg]) or a 3-band raster (sza, vza,
        raa: products that give the relative azimuth only) for ``angles_kind="geotiff"`` (or give
        the separate files ``sza`` ... ``vaa``, or ``sza``, ``vza``, ``raa``), else what
        :func:`brdfcorr.io.sensors.read_angles` reads for that kind (``envi_obs``, ``sentinel2``,
        ``landsat``, ``solar``, ...) with ``angle_options``, brought onto the image grid.
    wavelengths : sequence of float, optional
        Band centres [nm] replacing the image's (:func:`brdfcorr.io.rasters.open_image`).
    scale, offset : float, optional
        Reflectance factor per stored unit and of a stored 0, replacing the file's.
    label : str, optional
        How messages name the image (:attr:`image_label`) where ``image`` is not the path the user
        gave: a product folder or STAC item whose bands were stacked in a scratch virtual raster
        (:func:`brdfcorr.tasks.series.product_sources`) is named as given, not as that raster.
    """

    image: PathLike
    classes: PathLike | None
    angles: PathLike | None = None
    angles_kind: str = "geotiff"
    angle_options: Mapping[str, object] = field(default_factory=dict)
    sza: PathLike | None = None
    saa: PathLike | None = None
    vza: PathLike | None = None
    vaa: PathLike | None = None
    raa: PathLike | None = None
    wavelengths: Sequence[float] | None = None
    scale: float | None = None
    offset: float | None = None
    label: str | None = None

    @property
    def image_label(self) -> str:
        """The image as messages and reports name it: ``label``, else its path."""
        return self.label or str(self.image)

    def check_flip(self, flip_view_azimuth: bool) -> None:
        """Refuse a flip of the view azimuths read by a sensor reader (:func:`flip_refusal`)."""
        refusal = flip_refusal(self.angles_kind, flip_view_azimuth, option("flip_view_azimuth"))
        if refusal is not None:
            raise InputError(refusal)

    @property
    def inputs(self) -> list[tuple[str, PathLike | None]]:
        """The files read, by role (for the output guard, :func:`brdfcorr.io.paths.check_outputs`)."""
        return [("image", self.image), ("angles", None if self.angles_kind == "solar" else self.angles),
                ("sza raster", self.sza), ("saa raster", self.saa), ("vza raster", self.vza),
                ("vaa raster", self.vaa), ("raa raster", self.raa), ("class map", self.classes)]


class SceneData(NamedTuple):
    """One scene opened lazily and checked (:func:`open_scene`)."""

    reflectance: xr.DataArray
    """(band, y, x), nodata as NaN, with a ``wavelength`` coordinate [nm] where known."""
    classes: xr.DataArray
    """(y, x) integer class ids, with the file's nodata."""
    angles: dict[str, xr.DataArray]
    """``sza``, ``saa``, ``vza``, ``vaa`` (y, x) [deg] on the image grid."""
    statistics: AngleStatistics
    """Ranges and means of the angle layers (the scene-mean sun zenith among them)."""
    image: ImageFile | None = None
    """The image file identified once (:func:`brdfcorr.io.product.identify_image`: product kind,
    layout), None where it was opened by its path."""
    chunks: int | None = None
    """The spatial chunk size it was opened with [pixels] (:func:`opened_scene`)."""
    cache: int | None = None
    """GDAL's block cache [bytes] bounded while the scene is read and written (:func:`opened_scene`),
    None where not bounded."""
    threads: int | None = None
    """The dask threads of its passes (:func:`brdfcorr.io.writer.pass_threads`: the scale check's and
    the write's; None: the scheduler's own), worked out once (:func:`opened_scene`)."""


def open_scene(sources: SceneSources, *, chunks=None,
               prepare_classes: Callable[[xr.DataArray, xr.DataArray], xr.DataArray] | None = None,
               scheduler: str | None = None, num_workers: int | None = None,
               image: ImageFile | None = None) -> SceneData:
    """Open one scene lazily and check it: reflectance, class map and the four angle layers.

    Parameters
    ----------
    sources : SceneSources
        The files.
    chunks :
        As for :func:`brdfcorr.io.rasters.open_image`.
    prepare_classes : callable, optional
        ``prepare_classes(class_map, reflectance)`` -> class map, applied before the grid check:
        e.g. :func:`brdfcorr.strata.align_class_map` to bring a land-cover map on another grid onto
        the image's (an opt-in: by default a class map on another grid is an error).
    scheduler, num_workers : optional
        As for :func:`brdfcorr.io.angles.check_angles`.
    image : ImageFile, optional
        ``sources.image`` identified already (:func:`brdfcorr.io.product.identify_image`: its
        product kind and layout are not looked up again).

    Returns
    -------
    SceneData
        Reflectance (band, y, x), class map (y, x) and the angle layers by name, all on one grid
        (:func:`brdfcorr.io.grid.check_same_grid`) and with angles in degrees
        (:func:`brdfcorr.io.angles.check_angles`, the one pass over the angle data before the
        correction), with the angle statistics of that pass.
    """
    reflectance = open_image(sources.image if image is None else image, chunks=chunks,
                             wavelengths=sources.wavelengths, scale=sources.scale, offset=sources.offset)
    if sources.label:  # the grid checks' and other messages' name of its file (describe_layer)
        reflectance.encoding["label"] = sources.label
    if sources.classes is None:  # one class for the whole image, lazily on its grid
        first = reflectance[0]
        band_coords = [name for name in first.coords if name not in (*first.dims, "spatial_ref")]
        class_map = xr.ones_like(first, dtype="uint8").drop_vars(band_coords).rename("classes")
        class_map.attrs = {}
    else:
        class_map = open_classes(sources.classes, chunks=chunks)
    if prepare_classes is not None:
        class_map = prepare_classes(class_map, reflectance)
    if sources.angles_kind == "geotiff":
        layers = open_angles(sources.angles, sza=sources.sza, saa=sources.saa, vza=sources.vza, vaa=sources.vaa,
                             raa=sources.raa, chunks=chunks)
        source = None
    else:
        from brdfcorr.io.sensors import read_angles

        where = f"{sources.angles} ({sources.angles_kind})"
        if "like" in sources.angle_options:  # read_angles' own argument: the image
            raise InputError(f"angle option 'like' is no option of angle kind {sources.angles_kind!r}: the angles "
                             "are put on the image's grid")
        dataset = read_angles(sources.angles_kind, sources.angles, like=reflectance, **sources.angle_options)
        missing = [name for name in ANGLE_NAMES if name not in dataset]
        if missing:
            raise InputError(f"angle source {where} gives no {', '.join(missing)}")
        layers = {name: dataset[name] for name in ANGLE_NAMES}
        source = where
    if prepare_classes is None and sources.classes is not None:
        check_class_grid(reflectance, class_map)
    check_same_grid({"image": reflectance, "classes": class_map, **layers})
    statistics = check_angles(layers, source=source, scheduler=scheduler, num_workers=num_workers)
    return SceneData(reflectance, class_map, layers, statistics, image)


@contextlib.contextmanager
def opened_scene(sources: SceneSources, *, chunks: int | None = None,
                 prepare_classes: Callable[[xr.DataArray, xr.DataArray], xr.DataArray] | None = None,
                 scheduler: str | None = None, num_workers: int | None = None) -> Iterator[SceneData]:
    """One scene for a whole run (a correction): its image identified once (product kind, layout:
    :func:`brdfcorr.io.product.identify_image`), its chunk size worked out from that
    (:func:`brdfcorr.io.product.auto_chunk`) unless given, GDAL's block cache bounded
    (:func:`brdfcorr.io.product.gdal_cache_bytes`) from here to the end of the ``with`` block, the
    scene opened and checked (:func:`open_scene`), and, without a given scale
    (``sources.scale``), a sample of the image checked for raw counts
    (:func:`brdfcorr.io.scale_check.check_reflectance_scale`, a few chunks read, not a pass).

    The checks before the write read tiles; GDAL's default cache (5 % of RAM) would keep them for
    the rest of the run (issue 28). The :class:`SceneData` given carries the image, the chunk size,
    the cache and the thread count of its passes, so nothing after works them out again.

    Parameters
    ----------
    sources : SceneSources
        The files.
    chunks : int, optional
        Spatial chunk (and tile) size [pixels]; default :func:`brdfcorr.io.product.auto_chunk`.
    prepare_classes, scheduler, num_workers : optional
        As for :func:`open_scene`.

    Raises
    ------
    InputError
        As :func:`open_scene` and :func:`brdfcorr.io.scale_check.check_reflectance_scale`; an image
        that cannot be identified says so when its chunk size was to be worked out from it, else
        as :func:`open_scene` opens it.
    """
    image = _identified(sources.image, chunks)
    chunks = auto_chunk(image) if chunks is None else int(chunks)  # (image None: chunks given)
    cache = None if image is None else gdal_cache_bytes(image, chunks)
    threads = pass_threads(scheduler, num_workers)  # the scale check's, as the write's
    with rasterio.Env(GDAL_CACHEMAX=cache) if cache else contextlib.nullcontext():
        scene = open_scene(sources, chunks=chunks, image=image, prepare_classes=prepare_classes,
                           scheduler=scheduler, num_workers=num_workers)
        if sources.scale is None:  # a given scale is the user's word; else catch raw counts first
            scale_check.check_reflectance_scale(scene.reflectance, sources.image_label, scheduler=scheduler,
                                            num_workers=threads)
        yield scene._replace(image=image, chunks=chunks, cache=cache, threads=threads)


def _identified(path, chunks: int | None) -> ImageFile | None:
    """The image identified (:func:`brdfcorr.io.product.identify_image`); where it cannot be, its
    error when the chunk size is to be worked out from it, else None: :func:`open_scene` names the
    image that cannot be read, in its order."""
    try:
        return identify_image(path)
    except BrdfcorrError:
        if chunks is None:
            raise
        return None


def check_class_grid(image: xr.DataArray, class_map: xr.DataArray, image_name: str = "image") -> None:
    """:func:`~brdfcorr.io.grid.check_same_grid` of a class map and its image, whose message names
    the fix: the class map brought onto the image's grid (``--align-classes`` on the command line;
    :func:`brdfcorr.strata.align_class_map` in Python, in the caller's words, :mod:`brdfcorr._entry`)."""
    try:
        check_same_grid({image_name: image, "classes": class_map})
    except GridMismatchError as error:
        raise GridMismatchError(f"{error}; a land-cover map on another grid is brought onto the {image_name}'s with "
                                f"{option('align_classes')}") from None
