"""The ``steps:`` section of a chain config: strata, fit, correct (with terrain), assess and quicklook.

:class:`StepsConfig` holds one optional model per step: :class:`StrataStep`, :class:`ImageryFit` or
:class:`GoniometerFit` (with its :class:`MeasurementSet` tables), :class:`CorrectStep` (with
:class:`TerrainStep`), :class:`AssessStep` and :class:`QuicklookStep`. Pydantic models, validated as
part of :class:`brdfcorr.chain.config.ChainConfig`; import them from
:mod:`brdfcorr.chain.config`.

The keys a step shares with its command (``unknown`` of ``correct``, ``max_samples`` of
``fit-classes``, ...) are not written here: :func:`step_fields` makes them from the command's
settings in :mod:`brdfcorr.tasks.options` (type, words, default, bounds), and the step's class
derives from that model; only the chain's own keys and the checks across keys are written here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Field, create_model, field_validator, model_validator

from brdfcorr._validation import Integer, Number, PositiveInteger, StrictModel
from brdfcorr.chain.patterns import check_pattern
from brdfcorr.defaults import AUTO_MODEL, DEFAULT_EDGES, MOSTLY_UNCORRECTED, frame_conflict
from brdfcorr.errors import UnknownNameError
from brdfcorr.fit.prior import ShapePrior
from brdfcorr.fit.settings import WATER_VAPOUR_BANDS, ClassModels, GuardRails, Sampling, fallback_entry
from brdfcorr.models import SURFACE_MODELS
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.tasks.options import ASSESS, CORRECT, FIT_CLASSES, Setting, Settings

__all__ = [
    "StrataStep",
    "MeasurementSet",
    "GoniometerFit",
    "ImageryFit",
    "TerrainStep",
    "CorrectStep",
    "AssessStep",
    "QuicklookStep",
    "StepsConfig",
]

#: A surface model of the registry (its names are the allowed values).
SurfaceModel = Literal[SURFACE_MODELS]  # type: ignore[valid-type]
#: ... or ``auto``, the model with the lowest held-out error, where a step fits one.
FitModel = Literal[(*SURFACE_MODELS, AUTO_MODEL)]  # type: ignore[valid-type]


_KEY_TYPES: dict[str, Any] = {"flag": bool, "float": Number, "int": Integer, "text": str}


def _key_type(setting: Setting) -> Any:
    """The type of a chain key: a word of the setting's choices, a bool, a number or a text;
    null allowed where the default is None."""
    key_type = Literal[setting.choices] if setting.kind == "choice" else _KEY_TYPES[setting.kind]
    return Optional[key_type] if setting.default is None else key_type  # noqa: UP045 (a runtime type)


def step_fields(table: Settings, step: str) -> type[StrictModel]:
    """A model of the keys of the chain step ``step`` (or section: ``"inputs"``): the settings of a
    command's ``table`` (:mod:`brdfcorr.tasks.options`) marked with that step, each with the
    setting's type, words, default and bounds, and the chain's own bounds over them. A step's
    class derives from it."""
    fields = {setting.name: (_key_type(setting),
                             Field(setting.default, **{**setting.bounds(), **dict(setting.chain_bounds)}))
              for setting in table if setting.chain == step}
    return create_model(f"{step.title()}Keys", __base__=StrictModel, __module__=__name__, **fields)


class StrataStep(StrictModel):
    """The class map of every scene derived from its own image: NDVI strata (``brdfcorr classes
    ndvi``, :func:`brdfcorr.tasks.classmaps.ndvi_class_file`), written to ``outputs.strata_naming``
    before the fit, and the class map the fit, correct, assess and quicklook steps use (in place of
    ``inputs.classes``).

    Attributes
    ----------
    edges : list of float, optional
        Fixed NDVI edges [1], strictly increasing: n edges give strata 1..n+1, the same in every
        scene (``--edges``). Default :data:`brdfcorr.defaults.DEFAULT_EDGES` (0.1, 0.3, 0.5, 0.7)
        unless ``percentiles`` is given.
    percentiles : list of float, optional
        Each scene's NDVI percentiles [%] as its edges instead (``--percentiles``): strata of about
        equal size, whose edges differ from scene to scene.
    water_id, shadow_id : int
        Class of water and of shadow pixels (``--water-id``, ``--shadow-id``): 0 (no class,
        left uncorrected; default) or an id above the strata.
    ndvi_interpolation : bool, default False
        Give the run's table an ``ndvi_interpolation:`` block over the strata in the table
        (:class:`brdfcorr.params.NdviInterpolation`): a stratum's pixel gets the coefficients
        interpolated in its own NDVI between the strata's centres (their mean NDVI in the scene
        corrected), FlexBRDF's continuous correction (``docs/classmaps.md``).
    """

    edges: list[Number] | None = Field(None, min_length=1)
    percentiles: list[Annotated[Number, Field(gt=0, lt=100)]] | None = Field(None, min_length=1)
    water_id: Integer = Field(0, ge=0, le=255)
    shadow_id: Integer = Field(0, ge=0, le=255)
    ndvi_interpolation: bool = False

    @field_validator("edges", "percentiles")
    @classmethod
    def _increasing(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not all(math.isfinite(b) and a < b for a, b in zip(value, value[1:])):
            raise ValueError(f"{list(value)} must be finite and strictly increasing")
        return value

    @model_validator(mode="after")
    def _ids(self) -> StrataStep:
        if self.edges is not None and self.percentiles is not None:
            raise ValueError("give edges or percentiles, not both")
        strata = self.strata_ids()
        for key, value in (("water_id", self.water_id), ("shadow_id", self.shadow_id)):
            if value in strata:
                raise ValueError(f"{key} {value} is the id of a stratum (1 to {strata[-1]}): give 0 or an id above")
        if self.water_id and self.water_id == self.shadow_id:
            raise ValueError(f"water_id and shadow_id are both {self.water_id}; give different ids or 0")
        return self

    def strata_ids(self) -> list[int]:
        """The class ids of the NDVI strata, in increasing NDVI: 1 to the number of edges + 1."""
        cuts = self.percentiles if self.percentiles is not None else self.edges or DEFAULT_EDGES
        return list(range(1, len(cuts) + 2))


class MeasurementSet(StrictModel):
    """One goniometer measurement table fitted as one class (``brdfcorr fit`` in a chain).

    Attributes
    ----------
    file : str
        Measurements CSV (``theta_i, theta_r, phi, brdf[, sigma, wavelength]``).
    class_id : int
        Class id in the parameter table (>= 1).
    name : str
        Class name.
    model : str
        Registered surface model (``brdfcorr models``).
    fixed, initial : dict of str to float
        Parameters held fixed / starting values (paper 003 fixes k = 0.25).
    min_phi, max_phi, max_zenith : float, optional
        Measurement selection [deg] (paper 003 fits phi >= 90).
    """

    file: str = Field(min_length=1)
    class_id: Integer = Field(ge=1)
    name: str = Field(min_length=1)
    model: FitModel = "torrance_sparrow"
    fixed: dict[str, Number] = Field(default_factory=dict)
    initial: dict[str, Number] = Field(default_factory=dict)
    min_phi: Number | None = Field(None, ge=0, le=180)
    max_phi: Number | None = Field(None, ge=0, le=180)
    max_zenith: Number | None = Field(None, gt=0, lt=90)


class GoniometerFit(StrictModel):
    """Fit step from goniometer measurements: one class per measurement table."""

    source: Literal["goniometer"]
    measurements: list[MeasurementSet] = Field(min_length=1)
    output: str = "fitted_params.yaml"

    @model_validator(mode="after")
    def _unique(self) -> GoniometerFit:
        ids = [m.class_id for m in self.measurements]
        if len(set(ids)) != len(ids):
            raise ValueError(f"class ids {ids} of measurements must be distinct")
        return self


class ImageryFit(step_fields(FIT_CLASSES, "fit")):  # type: ignore[misc]
    """Fit step from the imagery itself: per-class fits pooled over the run's scenes
    (:func:`brdfcorr.tasks.fit.fit_class_files`, as ``brdfcorr fit-classes``: the same
    options and defaults).

    Attributes
    ----------
    model : str, optional
        Registered surface model of every class (``--model``). null (default): chosen from the
        class maps, ``ross_thick_li_sparse`` where every map is NDVI strata (``brdfcorr classes
        ndvi``), else ``torrance_sparrow``.
    class_models : dict of int to str
        Models of single classes (``--class-model``).
    names : dict of int to str
        Class names (``--class-name``); default: the ``parameters.materials`` names, then the class
        maps' ``class_names`` tag, else ``class_<id>``.
    fixed : dict of str to float, optional
        Shape parameters held fixed (``--fix``; default k = 0.25 for the Torrance-Sparrow models).
    max_samples, seed, reflectance_scale :
        Pixels per class over all scenes, the sampler's seed, the stored values' scale [-].
    block_size : int
        Side [pixels] of the spatial blocks the errors are cluster-robust over (``--block-size``).
    levels : {"auto", "pooled", "pixel", "patch"}
        Whose brightness level is free (``--levels``; :class:`brdfcorr.fit.Sampling`).
    patch_size : int
        Side [pixels] of the patches of ``levels: patch`` (``--patch-size``).
    errors_cluster : {"one-way", "two-way"}
        Whether the errors are cluster-robust over the blocks alone or over the blocks and the scenes
        at once (``--errors-cluster``; :mod:`brdfcorr.fit.two_way`).
    min_samples, min_vza_spread, max_condition :
        Guard rails (:class:`brdfcorr.fit.GuardRails`): samples per class, 5-95 % view zenith
        spread [deg], condition number of the linear design [-].
    bad_bands : list of [float, float]
        Wavelength ranges [nm], ends included, left out of the fit (``--bad-bands``; ``[]``: none);
        bands an ENVI header's ``bbl`` marks bad are left out too. Default: the water-vapour
        bands (:data:`brdfcorr.fit.WATER_VAPOUR_BANDS`).
    fallback : str, optional
        Built-in material or coefficient set for classes that fail the guard rails.
    allow_uncorrected : bool, default False
        Whether classes that fail the guard rails (without a ``fallback``) may stay uncorrected:
        by default a scene with pixels of such a class is a failed scene (``brdfcorr run`` exits
        with 3, naming the class).
    prior : str, optional
        Built-in coefficient set whose kernel shape is a prior of the fitted RTLSR classes
        (``--prior``, :class:`brdfcorr.fit.ClassModels`' ``prior``).
    prior_spread : float, optional
        The prior's 1-sigma of the ratios f_vol/f_iso and f_geo/f_iso (``--prior-spread``; default
        :data:`brdfcorr.fit.prior.DEFAULT_PRIOR_SPREAD`); only with ``prior``.
    output : str
        The fitted table, in the output directory.
    """

    source: Literal["imagery"]
    model: FitModel | None = None
    class_models: dict[PositiveInteger, FitModel] = Field(default_factory=dict)
    names: dict[PositiveInteger, str] = Field(default_factory=dict)
    fixed: dict[str, Number] | None = None
    reflectance_scale: Number = Field(1.0, gt=0)
    bad_bands: list[tuple[Number, Number]] = Field(
        default_factory=lambda: [tuple(band_range) for band_range in WATER_VAPOUR_BANDS])
    allow_uncorrected: bool = False
    output: str = "fitted_params.yaml"

    @field_validator("prior")
    @classmethod
    def _prior(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                load_coefficients(value)
            except UnknownNameError as error:
                raise ValueError(error.args[0]) from None
        return value

    @model_validator(mode="after")
    def _spread_needs_prior(self) -> ImageryFit:
        if self.prior_spread is not None and self.prior is None:
            raise ValueError("prior_spread needs prior")
        return self

    @field_validator("fallback")
    @classmethod
    def _fallback(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                fallback_entry(value, 1, "check")
            except UnknownNameError as error:
                raise ValueError(error.args[0]) from None
        return value

    @field_validator("bad_bands")
    @classmethod
    def _ranges(cls, value: list[tuple[float, float]]) -> list[tuple[float, float]]:
        for low, high in value:
            if not (math.isfinite(low) and math.isfinite(high) and 0 < low <= high):
                raise ValueError(f"range [{low:g}, {high:g}] nm must be finite with 0 < low <= high")
        return value

    def fit_settings(self, names: Mapping[int, str] | None = None, flip_view_azimuth: bool = False) -> dict[str, Any]:
        """The step as the keyword arguments ``models``, ``sampling`` (with the bad bands) and
        ``guard`` of :func:`brdfcorr.tasks.fit.fit_class_files`; ``names`` are default class
        names (the step's ``names`` win); ``flip_view_azimuth`` is the chain's
        (:attr:`brdfcorr.chain.config.ChainConfig.flips_view_azimuth`: the scenes' view azimuths are
        stored as seen from the sensor, fitted as they are corrected)."""
        return {
            "models": ClassModels(self.model, class_models=self.class_models, fixed=self.fixed,
                                  fallback=self.fallback, names=self.names, default_names=names,
                                  prior=None if self.prior is None
                                  else ShapePrior.given(self.prior, self.prior_spread)),
            "sampling": Sampling(max_samples=self.max_samples, seed=self.seed, block_size=self.block_size,
                                 reflectance_scale=self.reflectance_scale, levels=self.levels,
                                 patch_size=self.patch_size, errors_cluster=self.errors_cluster,
                                 bad_bands=tuple(tuple(band_range) for band_range in self.bad_bands),
                                 flip_view_azimuth=flip_view_azimuth),
            "guard": GuardRails(min_samples=self.min_samples, min_vza_spread=self.min_vza_spread,
                                max_condition=self.max_condition),
        }


class TerrainStep(step_fields(CORRECT, "terrain")):  # type: ignore[misc]
    """Tilted surfaces in the correct step (:class:`brdfcorr.tasks.request.Terrain`,
    ``docs/terrain.md``); slope and aspect come from ``inputs.slope_aspect`` or ``inputs.dem``.

    Attributes
    ----------
    topographic : {"cosine", "c", "scs", "scs+c", "none"}
        Illumination correction before the BRDF step
        (:func:`brdfcorr.correction.topographic.topographic_correction`).
    brdf_frame : {"surface", "horizontal"}
        Evaluate the BRDF in each surface's own frame or in the horizontal frame. The empirical C
        of ``"c"`` and ``"scs+c"`` goes with ``"horizontal"`` only (it absorbs part of the BRDF's
        slope dependence).
    """

    @model_validator(mode="after")
    def _frame(self) -> TerrainStep:
        conflict = frame_conflict(self.topographic, self.brdf_frame)
        if conflict:
            raise ValueError(conflict)
        return self


class CorrectStep(step_fields(CORRECT, "correct")):  # type: ignore[misc]
    """The normalization step (:func:`brdfcorr.tasks.correct.correct_files`); the words and defaults
    are those of ``brdfcorr correct`` (:data:`brdfcorr.tasks.options.CORRECT`).

    Attributes
    ----------
    limits : (float, float) or None
        Limits of the correction factor [-] (default 0.2 to 5); null for none.
    unknown : {"keep", "nan"}
        Pixels of class 0 or of classes absent from the table: unchanged, or NaN.
    extrapolate : bool
        Let band centres outside a class's table wavelengths take the edge values.
    flip_view_azimuth : bool
        View azimuths are stored as seen from the sensor: add 180 deg (the imagery fit and the
        assess step read them so too). ``inputs.flip_view_azimuth``, where given, sets it.
    factor_at : {"pixels", "nodes"}
        Where the factor is evaluated: at every pixel, or at the nodes of a sensor's coarse angle
        grid (``angles_kind: sentinel2``) and interpolated to the pixels (one class, no class map,
        terrain or uncertainty; :mod:`brdfcorr.correction.nodes`).
    qa : bool
        Also write the QA flag raster.
    min_corrected_share : float
        Least share [0-1] of a scene's valid pixels the correction must touch (QA ``corrected``
        over the pixels with data): a scene under it is a failed scene (``brdfcorr run`` exits with
        3, naming the share and this key). Default 0.5, where ``brdfcorr correct`` warns
        (:data:`brdfcorr.defaults.MOSTLY_UNCORRECTED`); 0 where few corrected pixels are
        expected (a class map covering part of the scene).
    terrain : TerrainStep, optional
        Correct tilted surfaces (needs ``inputs.slope_aspect`` or ``inputs.dem``); null: a flat
        surface.
    """

    limits: tuple[Annotated[Number, Field(gt=0)], Annotated[Number, Field(gt=0)]] | None = CORRECT.default("limits")
    qa: bool = True
    min_corrected_share: Number = Field(MOSTLY_UNCORRECTED, ge=0, le=1)
    terrain: TerrainStep | None = None

    @field_validator("limits")
    @classmethod
    def _limits(cls, value):
        if value is not None and not value[0] <= 1.0 <= value[1]:
            raise ValueError(f"limits {list(value)} must satisfy lower <= 1 <= upper")
        return value


class AssessStep(step_fields(ASSESS, "assess")):  # type: ignore[misc]
    """The view-angle signal left in every scene, before and after the correction
    (:func:`brdfcorr.tasks.assess.assess_files`): ``{scene}_assess.json`` and the figure
    ``{scene}_assess_profiles.png`` (:func:`brdfcorr.plot.assess.write_assessment_figures`) in
    the output directory.

    Attributes
    ----------
    sign_by : {"sun", "track"}
        Sign of the view zenith (:func:`brdfcorr.analysis.assess.signed_view_zenith`): positive
        towards forward scattering (``sun``) or right of the flight direction (``track``).
    heading : float, optional
        Flight direction [deg] clockwise from north; needed for ``sign_by: track`` (only there).
    bin_width : float
        Width of the bins of signed view zenith of the across-track profiles [deg].
    min_vza : float
        The side ratio compares pixels with ``|signed vza| >= min_vza`` [deg] (and never 0).
    block_size : int
        Side [pixels] of the spatial blocks the slopes' 1-sigma is cluster-robust over.
    clusters : str, optional
        Name pattern (``{scene}``, ``{stem}``, ``{dir}``, ``{parent}``) of each scene's cluster
        layer: a raster on its grid of integer ids of the units whose pixels share their errors (a
        composite's day-of-year band, a flight-line id); the slopes' 1-sigma is cluster-robust over
        these instead of square blocks (``brdfcorr assess --clusters``).
    cluster_band : int
        The band of the cluster layer that holds the ids (``--cluster-band``).
    """

    clusters: str | None = Field(None, min_length=1)

    @field_validator("clusters")
    @classmethod
    def _clusters_pattern(cls, value: str | None) -> str | None:
        return value if value is None else check_pattern(value)

    @model_validator(mode="after")
    def _heading(self) -> AssessStep:
        if self.sign_by == "track" and self.heading is None:
            raise ValueError("sign_by 'track' needs the flight direction: set heading [deg]")
        if self.sign_by == "sun" and self.heading is not None:
            raise ValueError("heading is only used with sign_by 'track'")
        return self


class QuicklookStep(StrictModel):
    """Before/after quicklook PNG of every scene.

    Attributes
    ----------
    bands : list of int, optional
        1-based bands shown as red, green, blue (three), or one band in grey. Default: the bands
        nearest 665, 560 and 490 nm where the image's wavelengths are known and cover them, else
        bands 3, 2, 1 (band 1 of a one- or two-band image).
    percentiles : (float, float)
        Contrast stretch of both images together, applied to both panels so they compare [%].
    max_size : int
        Longest side of the quicklook [pixels]; larger images are block-averaged.
    """

    bands: list[PositiveInteger] | None = None
    percentiles: tuple[Annotated[Number, Field(ge=0, le=100)], Annotated[Number, Field(ge=0, le=100)]] = (1.0, 99.9)
    max_size: Integer = Field(800, ge=16)

    @field_validator("bands")
    @classmethod
    def _count(cls, value: list[int] | None) -> list[int] | None:
        if value is not None and len(value) not in (1, 3):
            raise ValueError(f"give 1 or 3 bands, got {len(value)}")
        return value

    @field_validator("percentiles")
    @classmethod
    def _order(cls, value):
        if not value[0] < value[1]:
            raise ValueError(f"percentiles {list(value)} must be increasing")
        return value


class StepsConfig(StrictModel):
    """The steps, always run in the order strata -> fit -> correct -> assess -> quicklook; leave one
    out (or null) to skip it. ``correct`` is on by default."""

    strata: StrataStep | None = None
    fit: Annotated[Union[ImageryFit, GoniometerFit], Field(discriminator="source")] | None = None
    correct: CorrectStep | None = Field(default_factory=CorrectStep)
    assess: AssessStep | None = None
    quicklook: QuicklookStep | None = None

    @model_validator(mode="after")
    def _something(self) -> StepsConfig:
        if self.correct is None and self.quicklook is not None:
            raise ValueError("quicklook compares input and corrected images: it needs the correct step")
        if self.correct is None and self.assess is not None:
            raise ValueError("assess compares input and corrected images: it needs the correct step")
        return self
