"""Per-class BRDF parameter tables: the YAML format, validation, interpolation to band centres.

A table pairs each land-cover class id of a class map with a registered surface model
(:data:`brdfcorr.models.SURFACE_MODELS`) and its parameters. A parameter is a scalar (every band),
a list with one value per image band, or, with ``wavelengths`` [nm], a list interpolated linearly to
the image's band centres. The file format is described in ``docs/parameter-tables.md``::

    reference: {sza: 30.0, vza: 0.0, raa: 0.0}      # optional default reference geometry
    classes:
      - id: 1
        name: roof_tile
        model: torrance_sparrow
        params: {t0: 0.0245, t1: 0.20, w: 0.0362, n: 1.77, k: 0.25}
      - id: 2
        name: grass
        model: empirical
        wavelengths: [450, 550, 650, 850]
        params: {a: [0.01, 0.02, 0.015, 0.05], b: 1.0, c: 0.02, t0: [0.02, 0.05, 0.03, 0.30]}

Example
-------
>>> from brdfcorr.params import ClassEntry, ParameterTable
>>> table = ParameterTable(classes=[
...     ClassEntry(id=2, name="grass", model="empirical", wavelengths=[450, 850],
...                params={"a": [0.01, 0.05], "b": 1.0, "c": 0.02, "t0": 0.03}),
... ])
>>> table = table.with_class(ClassEntry(id=1, name="roof_tile", model="torrance_sparrow",
...     params={"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}))
>>> table.class_ids
(1, 2)
>>> bands = table.for_bands(wavelengths=[550, 650])
>>> [round(float(a), 3) for a in bands[2].params["a"]]
[0.02, 0.03]
>>> table.to_xarray(wavelengths=[550, 650])["a"].sel({"class": 2}).values.round(3).tolist()
[0.02, 0.03]

A class fitted by ``brdfcorr fit`` or ``fit-classes`` also carries a ``fit:`` block
(:class:`FitRecord`): the source, N, chi^2/dof, R^2, the 1-sigma errors and the covariance of the
fitted parameters, which :meth:`ParameterTable.for_bands` resolves to the bands with the parameters
(:attr:`BandParameters.covariance`).

A class may list ``bad_bands``, wavelength ranges [nm] where it has no parameters (the bands
``fit-classes`` left out of its fit: water vapour, the ENVI header's ``bbl``); the correction
passes image bands there through uncorrected (:attr:`BandParameters.no_parameters`).

An optional ``ndvi_interpolation:`` block (:class:`NdviInterpolation`) names NDVI strata whose
linear coefficients the correction interpolates in each pixel's NDVI between the strata's centres,
as FlexBRDF does (:mod:`brdfcorr.correction.continuous`; ``docs/classmaps.md``).

Errors in a table raise :class:`brdfcorr.errors.ParameterError` naming the class and the parameter
(and the file, for :meth:`ParameterTable.load`).

This module holds the table, its classes and the file format; the ``fit:`` record and its checks
are in :mod:`brdfcorr.params_fit`, the resolution of a class to an image's bands
(:class:`BandParameters`, interpolation in wavelength) in :mod:`brdfcorr.params_bands`. Import
every name from here.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import xarray as xr
import yaml
from pydantic import BeforeValidator, Field, ValidationError, field_validator, model_validator

from brdfcorr._validation import Integer, Number, StrictModel, describe_errors, refuse_boolean, short_repr
from brdfcorr.errors import InputError, ParameterError, UnknownNameError
from brdfcorr.io.files import atomic_path, parse_yaml, read_document
from brdfcorr.models import SURFACE_MODELS, Model, get_model
from brdfcorr.models.materials import load_material, material_names
from brdfcorr.params_bands import MATERIAL_WAVELENGTH_TOLERANCE as MATERIAL_WAVELENGTH_TOLERANCE
from brdfcorr.params_bands import (
    BandParameters,
    band_covariance,
    band_values,
    bands_dataset,
    check_bad_bands,
    class_label,
    material_caveat,
    resolve_entry,
)
from brdfcorr.params_fit import ERROR_TOLERANCE as ERROR_TOLERANCE
from brdfcorr.params_fit import Count as Count
from brdfcorr.params_fit import Covariance as Covariance
from brdfcorr.params_fit import FitRecord
from brdfcorr.params_fit import Statistic as Statistic
from brdfcorr.strata import NIR_RANGE, RED_RANGE

__all__ = [
    "ReferenceGeometry",
    "ClassEntry",
    "FitRecord",
    "ParameterTable",
    "NdviInterpolation",
    "BandParameters",
    "merge_tables",
    "as_parameter_table",
]

SunZenith = Annotated[float | Literal["mean", "observed", "hls"], BeforeValidator(refuse_boolean)]


#: A reference sun zenith in (0, this) [deg] is refused as radians (pi/2 = 1.571): no one normalizes
#: to a sun within 1.6 deg of the zenith, while 0.78 (45 deg in radians) is a common slip.
RADIANS_BELOW = 1.6


class ReferenceGeometry(StrictModel):
    """The sun/view geometry a scene is normalized to.

    Attributes
    ----------
    sza : float or "mean" or "observed" or "hls"
        Reference solar zenith [deg] in [0, 90); ``"mean"`` for the scene mean of the observed solar
        zenith, ``"observed"`` to keep each pixel's own solar zenith (only the view is normalized),
        ``"hls"`` for HLS v1.4's sun zenith of the scene centre's latitude
        (:func:`brdfcorr.correction.reference.hls_sza`).
    vza : float
        Reference view zenith [deg] in [0, 90); 0 (nadir) by default.
    raa : float
        Reference relative azimuth [deg] in [0, 180] (``docs/conventions.md`` convention; 180 is forward
        scattering). Irrelevant at nadir.
    """

    sza: SunZenith = "observed"
    vza: Number = Field(0.0, ge=0.0, lt=90.0)
    raa: Number = Field(0.0, ge=0.0, le=180.0)

    @field_validator("sza")
    @classmethod
    def _check_sza(cls, value):
        if isinstance(value, float) and not 0.0 <= value < 90.0:
            raise ValueError(f"reference sza = {value:g} deg must be in [0, 90)")
        if isinstance(value, float) and 0.0 < value < RADIANS_BELOW:  # a sun 1.6 deg from the zenith: radians
            raise ValueError(f"reference sza = {value:g} looks like radians ({np.degrees(value):.4g} deg); "
                             "the reference angles are degrees")
        return value

    def describe(self) -> str:
        """One line for provenance tags and summaries, e.g. ``"sza=30 vza=0 raa=0"``."""
        sza = self.sza if isinstance(self.sza, str) else f"{self.sza:g}"
        return f"sza={sza} vza={self.vza:g} raa={self.raa:g}"


#: A parameter's value: a number or a list of numbers; a boolean (YAML's ``yes``, ``on``) is refused.
ParameterValue = Annotated[float | list[Number], BeforeValidator(refuse_boolean)]
#: A wavelength range [nm] ``[low, high]``, ends included (:attr:`ClassEntry.bad_bands`).
BandRange = Annotated[list[Number], Field(min_length=2, max_length=2)]


class ClassEntry(StrictModel):
    """One class of a parameter table: its id in the class map, its model and parameters.

    Attributes
    ----------
    id : int
        Class id in the class map, >= 1 (0 means "no class").
    name : str
        Human-readable class name (``"roof_tile"``).
    model : str
        Registered surface model name (:data:`brdfcorr.models.SURFACE_MODELS`).
    params : dict of str to float or list of float
        Every parameter of the model, in its registry units. A list has one entry per image band or,
        with ``wavelengths``, one entry per wavelength.
    wavelengths : list of float, optional
        Strictly increasing wavelengths [nm] at which list-valued parameters are given.
    material : str, optional
        A built-in material (:mod:`brdfcorr.models.materials`) given instead of ``model`` and
        ``params``: ``{id: 1, material: roof_tile}`` takes the material's model and its
        band-independent parameters, and ``name`` defaults to the material's name. Kept on the
        entry (library key) so that the correction can warn when the material's single-wavelength
        fit is applied to far-away bands; a saved table writes the resolved ``model`` and ``params``
        instead (:meth:`ParameterTable.to_dict`).
    fit : FitRecord, optional
        How the parameters were fitted and how well they are known (errors, covariance, chi-square
        per degree of freedom, N, R^2, source), written by ``brdfcorr fit`` and ``fit-classes``.
    bad_bands : list of [float, float], optional
        Wavelength ranges [nm], ends included, where the class has no parameters (bad bands: water
        vapour absorption, bands the ENVI header's ``bbl`` marks bad), written by ``fit-classes``
        for the bands it left out of the fit. An image band whose centre lies in one is passed
        through uncorrected and flagged ``band_uncorrected`` (:class:`brdfcorr.correction.QA`);
        the class's ``wavelengths`` lie outside them and are interpolated across them as usual
        for the other bands (:func:`brdfcorr.params_bands.band_values`).
    """

    id: Integer = Field(ge=1)
    name: str = Field(min_length=1)
    model: str
    params: dict[str, ParameterValue]
    wavelengths: list[Number] | None = None
    material: str | None = None
    fit: FitRecord | None = None
    bad_bands: list[BandRange] | None = None

    @property
    def label(self) -> str:
        """``"class 2 (grass)"``, the prefix of every message about this class."""
        return class_label(self)

    @property
    def brdf_model(self) -> Model:
        """The registered :class:`~brdfcorr.models.Model`."""
        return get_model(self.model)

    @model_validator(mode="before")
    @classmethod
    def _resolve_material(cls, data: object) -> object:
        # ``material: NAME`` stands for the material's model and parameters (and default name).
        if not isinstance(data, Mapping) or data.get("material") is None:
            return data
        name = data["material"]
        shown = data.get("name") or name
        printable = isinstance(shown, str) and len(shown) <= 60 and shown.isprintable()
        label = f"class {data.get('id', '?')} ({shown if printable else short_repr(shown, 60)})"
        given = [key for key in ("model", "params", "wavelengths") if key in data]
        if given:
            raise ValueError(
                f"{label}: 'material' replaces {', '.join(map(repr, given))}; give either 'material' "
                "or 'model' and 'params'"
            )
        if not isinstance(name, str):
            raise ValueError(f"{label}: material must be a name; built-in materials: {', '.join(material_names())}")
        try:
            material = load_material(name)
        except UnknownNameError:
            raise ValueError(
                f"{label}: unknown material {short_repr(name)}; built-in materials: {', '.join(material_names())}"
            ) from None
        return {**data, "name": data.get("name") or material.name, "material": material.name,
                "model": material.model.name, "params": dict(material.params)}

    def wavelength_caveat(self, wavelengths: Sequence[float] | None) -> str | None:
        """Why this class may not fit the image's bands, or None.

        A library ``material`` is a fit at one wavelength (paper 003: 550 nm) applied unchanged to
        every band; this says so when a band centre is more than
        :data:`MATERIAL_WAVELENGTH_TOLERANCE` [nm] from it. None for other classes and for unknown
        band wavelengths.
        """
        return material_caveat(self, wavelengths)

    @model_validator(mode="after")
    def _check(self) -> ClassEntry:
        if self.model not in SURFACE_MODELS:
            raise ValueError(
                f"{self.label}: unknown surface model {short_repr(self.model)}; known: {', '.join(SURFACE_MODELS)}"
            )
        model = get_model(self.model)
        if self.wavelengths is not None:
            wavelengths = np.asarray(self.wavelengths, dtype=float)
            if wavelengths.size == 0 or not np.all(np.isfinite(wavelengths)) or np.any(wavelengths <= 0):
                raise ValueError(f"{self.label}: wavelengths must be finite and > 0 [nm]")
            if np.any(np.diff(wavelengths) <= 0):
                raise ValueError(f"{self.label}: wavelengths must be strictly increasing")
        for name, value in self.params.items():
            if isinstance(value, list):
                if not value:
                    raise ValueError(f"{self.label}: parameter {name} is an empty list")
                if self.wavelengths is not None and len(value) != len(self.wavelengths):
                    raise ValueError(
                        f"{self.label}: parameter {name} has {len(value)} values but "
                        f"{len(self.wavelengths)} wavelengths"
                    )
        lengths = {len(v) for v in self.params.values() if isinstance(v, list)}
        if self.wavelengths is None and len(lengths) > 1:
            raise ValueError(
                f"{self.label}: per-band parameter lists differ in length ({sorted(lengths)}); "
                "give one value per band for each, or add 'wavelengths'"
            )
        try:
            model.validate({k: np.asarray(v, dtype=float) for k, v in self.params.items()})
        except ParameterError as error:
            raise ValueError(f"{self.label}: {error}") from None
        if self.fit is not None:
            self.fit.check_entry(self, model)
        if self.bad_bands is not None:
            check_bad_bands(self)
        return self

    def band_values(
        self,
        wavelengths: Sequence[float] | None = None,
        n_bands: int | None = None,
        extrapolate: bool = False,
    ) -> dict[str, np.ndarray]:
        """The parameters at the image's bands, one float64 array of shape (n_bands,) each.

        Parameters
        ----------
        wavelengths : sequence of float, optional
            Band-centre wavelengths of the image [nm]; needed when the entry has ``wavelengths``.
        n_bands : int, optional
            Number of image bands; defaults to ``len(wavelengths)``.
        extrapolate : bool, default False
            Allow band centres outside the entry's wavelength range; they take the edge value.

        Raises
        ------
        ParameterError
            Naming the class and parameter, when the values cannot be mapped to the bands.
        """
        return band_values(self, wavelengths, n_bands, extrapolate)

    def band_covariance(
        self,
        wavelengths: Sequence[float] | None = None,
        n_bands: int | None = None,
        extrapolate: bool = False,
    ) -> np.ndarray | None:
        """The fit's covariance at the image's bands, shape (n_bands, p, p), or None without a fit.

        Resolved as :meth:`band_values` resolves the parameters: matrices given per wavelength are
        interpolated element-wise, linearly in wavelength (a convex combination of covariance
        matrices, so still positive semi-definite), with the same edge-extrapolation rule; matrices
        given per band are taken as they are; a single matrix applies to every band. Rows and
        columns follow ``fit.parameters``.
        """
        return band_covariance(self, wavelengths, n_bands, extrapolate)


class NdviInterpolation(StrictModel):
    """A group of classes whose coefficients vary continuously with NDVI (FlexBRDF), the
    ``ndvi_interpolation:`` block of a table.

    The classes are NDVI strata fitted one by one (``brdfcorr classes ndvi``, ``fit-classes``). The
    correction gives a pixel of any class of the group the parameters interpolated linearly in its
    own NDVI between the classes' NDVI centres (:mod:`brdfcorr.correction.continuous`), so that the
    strata's boundaries and a stratum's mixture changing across the scene stop biasing the
    correction (Queally et al. 2022, FlexBRDF, JGR Biogeosciences 127, e2021JG006622, sect. 2.3).

    Attributes
    ----------
    classes : list of int
        Class ids of the group, at least two, in increasing NDVI; each is a class of the table.
        They share one model with linear parameters (kernel-driven, Lambertian) and, band by band,
        equal shape parameters: only the linear coefficients are interpolated.
    centres : list of float, optional
        The NDVI [1] of each class, strictly increasing, one per class. Default: the mean NDVI of
        each class's pixels in the scene being corrected (one more read of its red and NIR bands).
    red, nir : (float, float)
        Wavelength ranges [nm] of the NDVI (:func:`brdfcorr.strata.ndvi`), ends included.
    """

    classes: list[Integer] = Field(min_length=2)
    centres: list[Number] | None = None
    red: tuple[Number, Number] = RED_RANGE
    nir: tuple[Number, Number] = NIR_RANGE

    @model_validator(mode="after")
    def _check(self) -> NdviInterpolation:
        if len(set(self.classes)) != len(self.classes):
            raise ValueError(f"ndvi_interpolation: classes {self.classes} list an id more than once")
        if self.centres is not None:
            centres = np.asarray(self.centres, dtype=float)
            if centres.size != len(self.classes):
                raise ValueError(f"ndvi_interpolation: {centres.size} centres for {len(self.classes)} classes; "
                                 "give one NDVI centre per class")
            if not np.all(np.isfinite(centres)) or np.any(np.diff(centres) <= 0):
                raise ValueError("ndvi_interpolation: centres must be finite and strictly increasing "
                                 "(list the classes in increasing NDVI)")
        for role, (low, high) in (("red", self.red), ("nir", self.nir)):
            if not 0 < low <= high:
                raise ValueError(f"ndvi_interpolation: {role} range {low:g}-{high:g} nm must be 0 < low <= high")
        return self

    def check_classes(self, table: ParameterTable) -> None:
        """Raise ``ValueError`` unless every class of the group is in ``table``, with one model that
        has linear parameters."""
        missing = [class_id for class_id in self.classes if class_id not in table]
        if missing:
            raise ValueError(f"ndvi_interpolation: class(es) {', '.join(map(str, missing))} are not in the table")
        models = sorted({table[class_id].model for class_id in self.classes})
        if len(models) > 1:
            raise ValueError(f"ndvi_interpolation: the classes must share one model, got {', '.join(models)}")
        if not get_model(models[0]).linear:
            raise ValueError(f"ndvi_interpolation: model {models[0]} has no linear parameters to interpolate")


def check_distinct_ids(entries: Iterable[ClassEntry]) -> None:
    """Raise ``ValueError`` (in a pydantic validator) when two of ``entries`` share a class id."""
    duplicates = sorted(i for i, count in Counter(entry.id for entry in entries).items() if count > 1)
    if duplicates:
        raise ValueError(f"class id(s) {', '.join(map(str, duplicates))} appear more than once")


class ParameterTable(StrictModel):
    """Per-class BRDF models and parameters, with an optional default reference geometry.

    Construct from keywords or :meth:`from_dict`, read with :meth:`load`, write with :meth:`save`.
    Tables are immutable: :meth:`with_class` returns a new table. Invalid content raises
    :class:`~brdfcorr.errors.ParameterError` naming the class and the parameter.
    """

    reference: ReferenceGeometry | None = None
    classes: list[ClassEntry] = Field(default_factory=list)
    ndvi_interpolation: NdviInterpolation | None = None

    def __init__(self, source: str = "parameter table", /, **data):
        # ``source`` (positional only, so no key of a document can set it) names the document in
        # messages (:meth:`from_dict`).
        try:
            super().__init__(**data)
        except ValidationError as error:
            raise ParameterError(f"{source}: {describe_errors(error, ParameterTable, data)}") from None

    @model_validator(mode="after")
    def _unique_ids(self) -> ParameterTable:
        check_distinct_ids(self.classes)
        if self.ndvi_interpolation is not None:
            self.ndvi_interpolation.check_classes(self)
        return self

    # ----------------------------------------------------------------------------------- access
    @property
    def class_ids(self) -> tuple[int, ...]:
        """Class ids, sorted."""
        return tuple(sorted(entry.id for entry in self.classes))

    def __getitem__(self, class_id: int) -> ClassEntry:
        for entry in self.classes:
            if entry.id == class_id:
                return entry
        raise KeyError(class_id)

    def __contains__(self, class_id: object) -> bool:
        return any(entry.id == class_id for entry in self.classes)

    def __len__(self) -> int:
        return len(self.classes)

    def with_class(self, entry: ClassEntry | Mapping, replace: bool = True) -> ParameterTable:
        """A new table with ``entry`` added, or replacing the class of the same id.

        Parameters
        ----------
        entry : ClassEntry or mapping
            The class (a mapping is validated as a :class:`ClassEntry`).
        replace : bool, default True
            If False, an existing class with the same id is an error.
        """
        if not isinstance(entry, ClassEntry):
            entry = ParameterTable(classes=[entry]).classes[0]
        if not replace and entry.id in self:
            raise ParameterError(f"class {entry.id} is already in the parameter table")
        classes = sorted([c for c in self.classes if c.id != entry.id] + [entry], key=lambda c: c.id)
        return self.model_copy(update={"classes": classes})

    def without_class(self, class_id: int) -> ParameterTable:
        """A new table without class ``class_id`` (also left out of its NDVI interpolation, which is
        dropped when fewer than two classes remain)."""
        self[class_id]  # KeyError if absent
        interpolation = self.ndvi_interpolation
        if interpolation is not None and class_id in interpolation.classes:
            keep = [k for k, value in enumerate(interpolation.classes) if value != class_id]
            centres = interpolation.centres
            interpolation = None if len(keep) < 2 else interpolation.model_copy(update={
                "classes": [interpolation.classes[k] for k in keep],
                "centres": None if centres is None else [centres[k] for k in keep]})
        return self.model_copy(update={"classes": [c for c in self.classes if c.id != class_id],
                                       "ndvi_interpolation": interpolation})

    def with_reference(self, reference: ReferenceGeometry | Mapping | None) -> ParameterTable:
        """A new table with another default reference geometry (None removes it)."""
        if reference is not None and not isinstance(reference, ReferenceGeometry):
            reference = ParameterTable(reference=reference).reference
        return self.model_copy(update={"reference": reference})

    def with_ndvi_interpolation(self, interpolation: NdviInterpolation | Mapping | None) -> ParameterTable:
        """A new table whose coefficients vary continuously with NDVI over a group of classes
        (:class:`NdviInterpolation`, e.g. ``{"classes": [1, 2, 3, 4, 5]}``); None removes it."""
        if interpolation is not None and not isinstance(interpolation, NdviInterpolation):
            interpolation = ParameterTable(classes=self.classes, ndvi_interpolation=interpolation).ndvi_interpolation
        return ParameterTable(reference=self.reference, classes=self.classes, ndvi_interpolation=interpolation)

    # ----------------------------------------------------------------------------- band values
    def for_bands(
        self,
        wavelengths: Sequence[float] | None = None,
        n_bands: int | None = None,
        extrapolate: bool = False,
    ) -> dict[int, BandParameters]:
        """Every class's parameters at the image's bands, by class id.

        Parameters
        ----------
        wavelengths : sequence of float, optional
            Band-centre wavelengths [nm]; required if any class gives values per wavelength.
        n_bands : int, optional
            Number of bands; defaults to ``len(wavelengths)``.
        extrapolate : bool, default False
            Let band centres outside a class's wavelength range take the edge value instead of
            raising :class:`~brdfcorr.errors.ParameterError`.
        """
        return {
            entry.id: resolve_entry(entry, wavelengths, n_bands, extrapolate)
            for entry in sorted(self.classes, key=lambda c: c.id)
        }

    def to_xarray(
        self,
        wavelengths: Sequence[float] | None = None,
        n_bands: int | None = None,
        extrapolate: bool = False,
    ) -> xr.Dataset:
        """The table at the image's bands as a Dataset of (class, band) parameter arrays.

        One variable per parameter name used by any class (NaN for classes whose model lacks it),
        with coordinates ``class`` (id), ``name`` and ``model`` along ``class`` and ``band``
        (1-based) with ``wavelength`` [nm] along ``band`` when given.
        """
        return bands_dataset(self.for_bands(wavelengths, n_bands, extrapolate), wavelengths, n_bands)

    # ------------------------------------------------------------------------------ file format
    @classmethod
    def from_dict(cls, data: object, source: str = "parameter table") -> ParameterTable:
        """Validate a parsed YAML document; errors name ``source``, the class and the parameter."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"{source}: expected a mapping with 'classes', got {type(data).__name__}")
        return cls(source, **{str(key): value for key, value in data.items()})

    @classmethod
    def from_yaml_text(cls, text: str, source: str = "parameter table") -> ParameterTable:
        """Parse YAML text (``yaml.safe_load``) and validate it."""
        data = parse_yaml(text, source, ParameterError)
        return cls.from_dict(data if data is not None else {}, source)

    @classmethod
    def load(cls, path: str | os.PathLike) -> ParameterTable:
        """Read and validate a YAML parameter table; errors name the file.

        Only a regular UTF-8 file of at most :data:`brdfcorr.io.files.MAX_DOCUMENT_BYTES` is read
        (:func:`brdfcorr.io.files.read_document`): a FIFO or a device is refused, not waited on.
        """
        path = Path(path)
        text = read_document(path, "parameter table", InputError)
        return cls.from_yaml_text(text, source=str(path))

    def to_dict(self) -> dict:
        """The table as plain Python data in the file format (unset optional keys left out).

        A class given as a built-in ``material`` is written with its resolved ``model`` and
        ``params``: a saved table (and the provenance tag of a corrected image) holds the numbers
        used, whatever later versions of the library hold, and stays readable by brdfcorr versions
        without the ``material`` key.
        """
        document: dict = {}
        if self.reference is not None:
            document["reference"] = self.reference.model_dump()
        document["classes"] = [
            entry.model_dump(exclude_none=True, exclude={"material"})
            for entry in sorted(self.classes, key=lambda c: c.id)
        ]
        if self.ndvi_interpolation is not None:
            document["ndvi_interpolation"] = self.ndvi_interpolation.model_dump(exclude_none=True)
        return document

    def to_yaml_text(self) -> str:
        """The table as YAML text (block style, keys in format order)."""
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the table as YAML, atomically (temporary name renamed when complete)."""
        path = Path(path)
        with atomic_path(path) as temporary:
            temporary.write_text(self.to_yaml_text())
        return path


def merge_tables(tables: Iterable[ParameterTable]) -> ParameterTable:
    """Combine tables; later tables replace classes of the same id, the last reference and the last
    NDVI interpolation win."""
    classes: dict[int, ClassEntry] = {}
    reference = interpolation = None
    for table in tables:
        classes.update((entry.id, entry) for entry in table.classes)
        if table.reference is not None:
            reference = table.reference
        if table.ndvi_interpolation is not None:
            interpolation = table.ndvi_interpolation
    return ParameterTable(reference=reference, classes=sorted(classes.values(), key=lambda c: c.id),
                          ndvi_interpolation=interpolation)



def as_parameter_table(params: ParameterTable | str | os.PathLike, argument: str = "params") -> ParameterTable:
    """The table a caller means by ``params``: a :class:`ParameterTable` as it is, a YAML file, or
    (where no such file exists) a built-in coefficient set by name (``"roy2017"``,
    :mod:`brdfcorr.models.coefficients`) as class 1, its weights interpolated to the band centres:
    what ``brdfcorr correct --params`` takes, for Python callers too.

    Raises
    ------
    InputError
        Neither a table nor a path or name (the message names ``argument``); a file that is missing
        or no parameter table (the message names it).
    """
    from brdfcorr.models.coefficients import coefficient_names, load_coefficients

    if isinstance(params, ParameterTable):
        return params
    if not isinstance(params, (str, os.PathLike)):
        raise InputError(f"{argument} must be a ParameterTable, a parameter table file or a coefficient set name "
                         f"({', '.join(coefficient_names())}), got {type(params).__name__}")
    path = Path(params)
    if not path.exists() and str(params).strip().lower() in coefficient_names():
        return ParameterTable(classes=[ClassEntry(**load_coefficients(str(params)).table_entry(1))])
    return ParameterTable.load(path)  # a missing file: the error names it
