"""A parameter table (:class:`ParameterTable`): classes by id, an optional default reference
geometry (:class:`ReferenceGeometry`) and NDVI interpolation (:class:`NdviInterpolation`), and its
YAML file format (``docs/parameter-tables.md``).

The classes themselves are :class:`brdfcorr.params.entry.ClassEntry`. Import the names from
:mod:`brdfcorr.params`.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
import yaml
from pydantic import BeforeValidator, Field, ValidationError, field_validator, model_validator

from brdfcorr._validation import Integer, Number, StrictModel, describe_errors, refuse_boolean
from brdfcorr.defaults import NIR_RANGE, RED_RANGE
from brdfcorr.errors import InputError, ParameterError
from brdfcorr.io.files import atomic_path, parse_yaml, read_document
from brdfcorr.models import get_model
from brdfcorr.params.bands import BandParameters, bands_dataset, resolve_entry
from brdfcorr.params.entry import ClassEntry

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "ReferenceGeometry",
    "ParameterTable",
    "NdviInterpolation",
    "merge_tables",
    "as_parameter_table",
    "check_distinct_ids",
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

    def classes_without_errors(self) -> list[str]:
        """The labels of the classes with neither a ``fit:`` covariance nor a library material's
        published errors: their pixels are NaN in an uncertainty raster (``docs/uncertainty.md``)."""
        return [entry.label for entry in self.classes if entry.fit is None and entry.material is None]

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
    from brdfcorr.models.coefficients import coefficient_names

    if isinstance(params, ParameterTable):
        return params
    if not isinstance(params, (str, os.PathLike)):
        raise InputError(f"{argument} must be a ParameterTable, a parameter table file or a coefficient set name "
                         f"({', '.join(coefficient_names())}), got {type(params).__name__}")
    path = Path(params)
    if not path.exists() and is_coefficient_name(str(params)):
        return coefficient_table(str(params))
    return ParameterTable.load(path)  # a missing file: the error names it


def is_coefficient_name(text: str) -> bool:
    """Whether ``text`` names a built-in coefficient set (``"roy2017"``, any case)."""
    from brdfcorr.models.coefficients import coefficient_names

    return text.strip().lower() in coefficient_names()


def coefficient_table(name: str) -> ParameterTable:
    """The built-in coefficient set ``name`` as a one-class table (class 1), per band."""
    from brdfcorr.models.coefficients import load_coefficients

    return ParameterTable(classes=[ClassEntry(**load_coefficients(name).table_entry(1))])
