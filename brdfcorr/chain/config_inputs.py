"""The sections of a chain config that say what a run reads: ``inputs:`` and ``parameters:``.

:class:`InputsConfig` (with :class:`AngleSource`) names the scenes and their per-scene sources,
:class:`ParametersConfig` the parameter table the run starts from. Pydantic models, validated as
part of :class:`brdfcorr.chain.config.ChainConfig`; import them from
:mod:`brdfcorr.chain.config`.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from brdfcorr._validation import Integer, Number, PositiveInteger, StrictModel, short_repr
from brdfcorr.chain.config_steps import step_fields
from brdfcorr.chain.patterns import check_pattern
from brdfcorr.errors import UnknownNameError
from brdfcorr.io.sensors import ANGLE_KINDS
from brdfcorr.models.materials import load_material, material_names
from brdfcorr.params import ClassEntry, check_distinct_ids
from brdfcorr.tasks.options import CHAIN_INPUTS

__all__ = ["AngleSource", "InputsConfig", "ParametersConfig", "check_material"]

#: ``geotiff`` or a sensor product kind of :data:`brdfcorr.io.sensors.ANGLE_KINDS`.
AngleKind = Literal[("geotiff", *ANGLE_KINDS)]  # type: ignore[valid-type]


class AngleSource(StrictModel):
    """Where a scene's sun/view angles come from.

    Attributes
    ----------
    kind : {"geotiff", "envi_obs", "sentinel2", "landsat", "solar"}
        ``geotiff``: a 4-band raster sza, saa, vza, vaa [deg] on the image grid; the others are
        sensor products read by :func:`brdfcorr.io.sensors.read_angles`.
    path : str
        Name pattern of the source: the angle raster, the obs file, the ``MTD_TL.xml``, the Landsat
        product; for ``solar`` the acquisition time (ISO 8601 with time zone).
    options : dict
        Keyword options of the kind's reader (e.g. ``{view_azimuth: from_sensor}``,
        ``{view_zenith: 0, view_azimuth: 0}`` for ``solar``).
    """

    kind: AngleKind = "geotiff"
    path: str = Field(min_length=1)
    options: dict[str, Any] = Field(default_factory=dict)

    @field_validator("path")
    @classmethod
    def _pattern(cls, value: str) -> str:
        return check_pattern(value)

    @model_validator(mode="after")
    def _options_for_kind(self) -> AngleSource:
        if self.kind == "geotiff" and self.options:
            raise ValueError(f"kind 'geotiff' takes no options, got {', '.join(self.options)}")
        return self


class InputsConfig(step_fields(CHAIN_INPUTS, "inputs")):  # type: ignore[misc]
    """The scenes of a run.

    Attributes
    ----------
    images : list of str
        Image paths or globs (``scenes/*_image.tif``); every match is one scene, sorted by path. Or
        product folders (``tiles/*.SAFE``: Sentinel-2 L2A SAFE, Landsat Collection-2 L2 folders,
        Sentinel-2 STAC item files with local assets), all of them: each product is one scene
        whose bands, scaling, wavelengths and angles come from the product
        (:mod:`brdfcorr.chain.products`), so ``angles``, ``scale``, ``offset`` and
        ``wavelengths`` are then left out.
    scene_regex : str, optional
        Regular expression with a named group ``scene``, matched on the image file name (or the
        product's folder or item name), giving the scene name used in patterns (default: the file
        stem).
    angles : AngleSource, optional
        Per-scene angle source; needed for image files, refused for products.
    classes : str, optional
        Name pattern of the per-scene class map raster; left out when ``steps.strata`` derives the
        class maps (NDVI strata of each image).
    align_classes : bool
        The class maps may lie on another grid or CRS (a land-cover product): resample them onto
        each image's grid by nearest neighbour (recorded in the outputs' tags). Default False: a
        class map on another grid is an error.
    class_lookup : dict of int to int
        Class-map code -> table class id (e.g. ESA WorldCover 10 -> 3); codes not listed: no class.
    slope_aspect, dem : str, optional
        Name patterns of the per-scene terrain source of ``steps.correct.terrain``
        (:class:`brdfcorr.tasks.correct.Terrain`): a 2-band slope/aspect raster [deg] (or an ENVI
        ``obs_ort`` file), or a DEM [m] in a projected CRS, on the image grid; give one of them.
    wavelengths : list of float, optional
        Band centres [nm] for every image, overriding what the files say.
    scale, offset : float, optional
        Reflectance factor per stored unit (> 0) and of a stored 0, for every image, for products
        that do not tag them (e.g. 0.0001 for 0-10000; Landsat C2 L2 2.75e-5 and -0.2); a given
        value replaces the files' GDAL scale/offset (default: the files', else 1 and 0). Applied on
        read by the fit and correct steps and recorded in the outputs' tags.
    flip_view_azimuth : bool, optional
        The angle sources store the view azimuths as seen from the sensor (towards the ground):
        180 deg is added to each, by the imagery fit, the correction and the assessment alike
        (``--flip-view-azimuth``, :data:`brdfcorr.tasks.options.CHAIN_INPUTS`). null (default):
        ``steps.correct.flip_view_azimuth`` decides, false without a correct step; a correct step
        that gives the other value is an error (:class:`brdfcorr.chain.config.ChainConfig`).
    """

    images: list[str] = Field(min_length=1)
    scene_regex: str | None = None
    angles: AngleSource | None = None
    classes: str | None = Field(None, min_length=1)
    align_classes: bool = False
    class_lookup: dict[Integer, Annotated[Integer, Field(ge=0, le=65535)]] = Field(default_factory=dict)
    slope_aspect: str | None = Field(None, min_length=1)
    dem: str | None = Field(None, min_length=1)
    wavelengths: list[Annotated[Number, Field(gt=0)]] | None = None
    scale: Number | None = Field(None, gt=0, allow_inf_nan=False)
    offset: Number | None = Field(None, allow_inf_nan=False)

    @field_validator("images")
    @classmethod
    def _no_empty(cls, value: list[str]) -> list[str]:
        if any(not item.strip() for item in value):
            raise ValueError("image paths must not be empty")
        return value

    @field_validator("scene_regex")
    @classmethod
    def _regex(cls, value: str | None) -> str | None:
        if value is None:
            return value
        try:
            compiled = re.compile(value)
        except re.error as error:
            raise ValueError(f"not a regular expression: {error}") from None
        if "scene" not in compiled.groupindex:
            raise ValueError(f"{short_repr(value)} has no named group (?P<scene>...)")
        return value

    @field_validator("classes")
    @classmethod
    def _pattern(cls, value: str | None) -> str | None:
        return value if value is None else check_pattern(value)

    @field_validator("slope_aspect", "dem")
    @classmethod
    def _terrain_pattern(cls, value: str | None) -> str | None:
        return value if value is None else check_pattern(value)

    @model_validator(mode="after")
    def _one_terrain_source(self) -> InputsConfig:
        if self.slope_aspect is not None and self.dem is not None:
            raise ValueError("give slope_aspect or dem, not both: slope and aspect come from one of them")
        return self


def check_material(name: str) -> str:
    """``name`` if it is a built-in material, else a ``ValueError`` (for a pydantic validator)
    listing them."""
    try:
        load_material(name)
    except UnknownNameError:
        allowed = ", ".join(map(repr, material_names()))
        raise ValueError(f"{short_repr(name)} is not a built-in material; allowed: {allowed}") from None
    return name


class ParametersConfig(StrictModel):
    """The parameter table of the run, merged from (later wins for a class id): built-in
    ``materials``, inline ``classes``, the ``table`` file, and the output of the ``fit`` step.

    Attributes
    ----------
    table : str, optional
        Parameter table YAML (``docs/parameter-tables.md`` format), or a built-in coefficient set's
        name (``roy2017``: class 1, :func:`brdfcorr.params.table.coefficient_table`) where no file
        has that name.
    materials : dict of int to str
        Class id -> built-in material name (paper 003, Table 1; ``brdfcorr materials``).
    classes : list
        Classes written inline, as under ``classes:`` of a parameter table file.
    """

    table: str | None = None
    materials: dict[PositiveInteger, str] = Field(default_factory=dict)
    classes: list[ClassEntry] = Field(default_factory=list)

    @field_validator("materials")
    @classmethod
    def _materials(cls, value: dict[int, str]) -> dict[int, str]:
        for name in value.values():
            check_material(name)
        return value

    @field_validator("classes")
    @classmethod
    def _unique(cls, value: list[ClassEntry]) -> list[ClassEntry]:
        check_distinct_ids(value)
        return value
