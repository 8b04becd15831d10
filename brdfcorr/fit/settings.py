"""The settings of an imagery fit, one frozen dataclass per concern: which model each class gets
(:class:`ClassModels`), how the pixels are sampled (:class:`Sampling`) and the guard rails a fit
must pass (:class:`GuardRails`); and the bands an imagery fit leaves out by default
(:data:`WATER_VAPOUR_BANDS`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from brdfcorr.errors import UnknownNameError
from brdfcorr.fit.prior import ShapePrior
from brdfcorr.models import Model
from brdfcorr.models.coefficients import coefficient_names, load_coefficients
from brdfcorr.models.materials import load_material, material_names

__all__ = ["GuardRails", "ClassModels", "Sampling", "WATER_VAPOUR_BANDS", "DEFAULT_MODEL", "STRATA_MODEL",
           "fallback_entry"]

#: Wavelength ranges [nm] of the strong water-vapour absorption bands (about 1.4 and 1.9 um), where
#: an imaging spectrometer's surface reflectance is mostly noise: an imagery fit leaves image bands
#: in them out (they get no parameters and are passed through uncorrected). The ranges of the bad
#: bands of AVIRIS-NG L2 reflectance and of HyTools/FlexBRDF configurations (Queally et al. 2022).
WATER_VAPOUR_BANDS: tuple[tuple[float, float], ...] = ((1340.0, 1450.0), (1800.0, 1960.0))
#: The model of an imagery fit's classes when none is chosen ...
DEFAULT_MODEL = "torrance_sparrow"
#: ... and when the class maps are NDVI strata (vegetation and soil: a kernel-driven model).
STRATA_MODEL = "ross_thick_li_sparse"


@dataclass(frozen=True)
class GuardRails:
    """Minimum requirements for a class fit to be used.

    Attributes
    ----------
    min_samples : int
        Minimum number of valid pixels of the class.
    min_vza_spread : float
        Minimum spread of the view zenith [deg] between its 5th and 95th percentiles.
    max_condition : float
        Maximum condition number of the column-normalized linear design (one column per intensity
        term); above it the terms (e.g. the constant and the specular term) cannot be told apart.
    min_r2 : float
        Minimum median (over bands) *angular* R^2 (:meth:`~brdfcorr.fit.profile._LinearProfile.angular_r2`:
        the fit against the data's means in bins of geometry, so that albedo texture does not count
        against it): below it the model explains (almost) none of the angular signal. Not applied
        to a model without angular variation (Lambertian).

    Notes
    -----
    A fit with a free shape parameter at an end of its search range
    (:func:`~brdfcorr.fit.shapes.search_range`, unless that end is a closed physical bound) fails
    as well when its angular R^2 is below :data:`POOR_R2`: the data do not constrain the parameter
    and the model does not follow the angular signal. With a good angular fit the parameter is
    only poorly determined (n of the Torrance-Sparrow model often is): that is noted, not failed.
    """

    min_samples: int = 500
    min_vza_spread: float = 10.0
    max_condition: float = 1e3
    min_r2: float = 0.05

    def spread_short(self, spread: float) -> str:
        """``"9.9 deg < 10 deg"``: a geometry spread [deg] below :attr:`min_vza_spread`, rounded
        down so that it never reads as the limit itself (9.96 is not "10.0 deg < 10 deg")."""
        return f"{math.floor(spread * 10) / 10:.1f} deg < {self.min_vza_spread:g} deg"


@dataclass(frozen=True)
class ClassModels:
    """Which classes an imagery fit fits, what they are called, and with which surface model.

    Attributes
    ----------
    model : str or Model or None, default "torrance_sparrow"
        Surface model with intensity terms (:func:`intensity_terms`) for every class ... (None:
        chosen from the class maps by :func:`brdfcorr.tasks.fit.fit_class_files`,
        :data:`STRATA_MODEL` for NDVI strata, else :data:`DEFAULT_MODEL`; "torrance_sparrow" for
        :func:`brdfcorr.fit.fit_classes`) ...
    class_models : mapping of int to str, optional
        ... except these classes (class id to model name), which get their own model.
    fixed : mapping of str to float, optional
        Shape parameters held fixed in every class whose model has them (default: k = 0.25 for
        the Torrance-Sparrow models, :data:`DEFAULT_FIXED`).
    fallback : str or mapping of int to str, optional
        Built-in material or coefficient set (:func:`fallback_entry`) used for a class that
        fails its guard rails, one for all classes or one per class id; without one the class is
        left out of the table (left uncorrected, and flagged by the correction).
    names : mapping of int to str, optional
        Class names (default ``class_<id>``).
    class_ids : sequence of int, optional
        Classes to fit (default: every positive id in the class maps).
    default_names : mapping of int to str, optional
        Names of the classes that ``names`` does not name (a class map's ``class_names`` tag, a
        chain's materials): they describe what a map may hold, so unlike ``names`` they are not
        checked against the classes found (:meth:`unused`).
    prior : ShapePrior, optional
        A coefficient set's kernel shape as the prior of every ``ross_thick_li_sparse`` class
        (:mod:`brdfcorr.fit.prior`): each band's weights and covariance are the posterior's, and
        the condition-number guard rail does not apply to those classes (the prior determines the
        shape the geometry cannot separate). Needs the bands' wavelengths.

    Examples
    --------
    >>> models = ClassModels("ross_thick_li_sparse", class_models={1: "torrance_sparrow"},
    ...                      names={1: "roof_tile", 2: "grass"})
    >>> models.model_of(1), models.model_of(2), models.name_of(3)
    ('torrance_sparrow', 'ross_thick_li_sparse', 'class_3')
    """

    model: str | Model | None = DEFAULT_MODEL
    class_models: Mapping[int, str] | None = None
    fixed: Mapping[str, float] | None = None
    fallback: str | Mapping[int, str] | None = None
    names: Mapping[int, str] | None = None
    class_ids: Sequence[int] | None = None
    prior: ShapePrior | None = None
    default_names: Mapping[int, str] | None = None

    def model_of(self, class_id: int) -> str | Model:
        """The surface model of class ``class_id``."""
        return (self.class_models or {}).get(class_id, DEFAULT_MODEL if self.model is None else self.model)

    def name_of(self, class_id: int) -> str:
        """The name of class ``class_id``: from ``names``, else ``default_names``, else ``class_<id>``."""
        return {**(self.default_names or {}), **(self.names or {})}.get(class_id, f"class_{class_id}")

    def fallback_of(self, class_id: int) -> str | None:
        """The built-in material of class ``class_id`` should its fit fail (None: left uncorrected)."""
        return self.fallback.get(class_id) if isinstance(self.fallback, Mapping) else self.fallback

    def unused(self, fitted: Iterable[int]) -> str | None:
        """What the per-class settings (``class_models``, ``names``, a ``fallback`` per class) say
        of classes outside ``fitted`` (the classes found in the class maps, or ``class_ids``),
        which would be ignored: one line naming them (a typo, 9 for 7, fits the wrong model
        without it), or None where every class they name is fitted."""
        settings = {"class_models": self.class_models, "names": self.names,
                    "fallback": self.fallback if isinstance(self.fallback, Mapping) else None}
        kept = set(fitted)
        named = {key: sorted(set(value or ()) - kept) for key, value in settings.items()}
        ids = sorted({ident for missing in named.values() for ident in missing})
        if not ids:
            return None
        where = "no class map holds" if self.class_ids is None else "the class_ids leave out"
        which = "; ".join(f"{key} {', '.join(map(str, missing))}" for key, missing in named.items() if missing)
        return (f"the class settings name class{'es' if len(ids) > 1 else ''} {', '.join(map(str, ids))} that "
                f"{where} ({which}): not used")


@dataclass(frozen=True)
class Sampling:
    """How an imagery fit pools and samples each class's pixels (:func:`sample_classes`).

    Attributes
    ----------
    max_samples : int, default 50000
        Cap on the samples per class, over all scenes together (without replacement, seeded).
    seed : int, default 0
        Seed of the sampler: the same inputs and seed give the same samples.
    reflectance_scale : float, default 1
        Multiplier that turns stored values into reflectance factors [-] (e.g. 1e-4 for
        0-10000).
    block_size : int, default 32
        Side [pixels] of the square spatial blocks that label the samples; the fit's errors are
        cluster-robust over these blocks.
    keep_samples : int, default 2000
        Samples per class kept in the result (:attr:`ClassFitResult.samples`) for plots.
    bad_bands : sequence of (float, float), default :data:`WATER_VAPOUR_BANDS`
        Wavelength ranges [nm], ends included, whose bands are not sampled nor fitted (their
        classes list them as ``bad_bands`` in the table).
    levels : {"auto", "pooled", "pixel", "patch"}, default "auto"
        Whose brightness level the fit leaves free (:data:`brdfcorr.fit.sampling.LEVELS`,
        :mod:`brdfcorr.fit.within`): ``auto`` frees every pixel's where several scenes share one
        grid (the shape is then fitted to each pixel's own views only) and pools a single scene.
    patch_size : int, default 8
        Side [pixels] of the patches of ``levels="patch"`` (a divisor of ``block_size``).
    errors_cluster : {"one-way", "two-way"}, default "one-way"
        Errors cluster-robust over the blocks (or pixels, patches, cluster-layer ids) alone, or
        over those and the scenes at once (Cameron, Gelbach and Miller 2011;
        :mod:`brdfcorr.fit.two_way`): for errors shared by every pixel of a date or line (its
        atmosphere, its calibration). With one scene both are the same.
    flip_view_azimuth : bool, default False
        The view azimuths are stored as seen from the sensor (towards the ground): 180 deg is added
        to each before the relative azimuth is formed, as :func:`brdfcorr.normalize` does with the
        same option, so that a table is fitted and applied in one convention.
    """

    max_samples: int = 50_000
    seed: int = 0
    reflectance_scale: float = 1.0
    block_size: int = 32
    keep_samples: int = 2000
    bad_bands: tuple[tuple[float, float], ...] = WATER_VAPOUR_BANDS
    levels: str = "auto"
    patch_size: int = 8
    errors_cluster: str = "one-way"
    flip_view_azimuth: bool = False


def fallback_entry(name: str, class_id: int, class_name: str) -> dict:
    """The parameter-table entry (:class:`brdfcorr.params.ClassEntry` fields) a class gets when
    its fit fails the guard rails and its fallback is ``name``: a built-in material
    (:func:`brdfcorr.models.materials.load_material`, band-independent parameters) or a built-in
    coefficient set (:func:`brdfcorr.models.coefficients.load_coefficients`: ``roy2016`` or
    ``roy2017``, the global RTLSR weights at their bands' centres, interpolated in wavelength to
    the image's bands by the table).

    Raises
    ------
    UnknownNameError
        ``name`` is neither; the message lists both kinds.
    """
    try:
        material = load_material(name)
    except UnknownNameError:
        pass
    else:
        return {"id": class_id, "name": class_name, "model": material.model.name, "params": material.params}
    try:
        return load_coefficients(name).table_entry(class_id, name=class_name)
    except UnknownNameError:
        raise UnknownNameError(f"unknown fallback {name!r}: neither a built-in material "
                               f"({', '.join(material_names())}) nor a built-in coefficient set "
                               f"({', '.join(coefficient_names())})") from None
