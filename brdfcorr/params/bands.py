"""A parameter-table class resolved to an image's bands (:class:`BandParameters`).

A class gives each parameter as a scalar, one value per band, or values at its own
``wavelengths`` [nm]; the functions here turn them, and the ``fit:`` covariance, into one value
(one p x p matrix) per image band, interpolating linearly in wavelength, and gather a whole table
into an xarray Dataset. A class's ``bad_bands`` (wavelength ranges [nm] without parameters) leave
the image bands in them without values (NaN, :attr:`BandParameters.no_parameters`). They back
:meth:`brdfcorr.params.ClassEntry.band_values`,
:meth:`~brdfcorr.params.ClassEntry.band_covariance`,
:meth:`~brdfcorr.params.ClassEntry.wavelength_caveat`,
:meth:`brdfcorr.params.ParameterTable.for_bands` and
:meth:`~brdfcorr.params.ParameterTable.to_xarray`; import the names from :mod:`brdfcorr.params`.
They read a class through :class:`ClassFields`, the attributes of
:class:`brdfcorr.params.ClassEntry` they use, so that this module imports no module above it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from brdfcorr._entry import option
from brdfcorr._validation import short_repr
from brdfcorr.errors import ParameterError
from brdfcorr.models import Model, get_model
from brdfcorr.models.materials import load_material
from brdfcorr.params.fit_record import EntryFields, FitRecord

if TYPE_CHECKING:  # xarray is imported where a Dataset is made: reading a table needs none
    import xarray as xr

__all__ = ["BandParameters", "ClassFields", "MATERIAL_WAVELENGTH_TOLERANCE", "in_ranges"]


class ClassFields(EntryFields, Protocol):
    """What the band resolution reads of a table class (:class:`brdfcorr.params.ClassEntry` has it)."""

    @property
    def id(self) -> int:
        """Class id in the class map, >= 1."""

    @property
    def name(self) -> str:
        """Human-readable class name."""

    @property
    def model(self) -> str:
        """Registered surface model name."""

    @property
    def material(self) -> str | None:
        """The built-in material the class was given as, or None."""

    @property
    def fit(self) -> FitRecord | None:
        """The ``fit:`` record, or None."""

    @property
    def bad_bands(self) -> Sequence[Sequence[float]] | None:
        """Wavelength ranges [nm], ends included, without parameters, or None."""

#: Distance [nm] between a band centre and a library material's fit wavelength beyond which the
#: correction warns (:meth:`ClassEntry.wavelength_caveat`).
MATERIAL_WAVELENGTH_TOLERANCE = 100.0


@dataclass(frozen=True)
class BandParameters:
    """A class's model and its parameters resolved to an image's bands.

    Attributes
    ----------
    id, name : int, str
        Class id and name.
    model : Model
        The registered model.
    params : dict of str to ndarray
        One float64 array of shape (n_bands,) per model parameter, in signature order.
    covariance : ndarray or None
        The fit's covariance of the parameters ``covariance_names`` at each band, shape
        (n_bands, p, p), in products of registry units; None when the class has no ``fit`` block.
        Parameters not in ``covariance_names`` were held fixed (zero variance).
    covariance_names : tuple of str
        The parameters of the covariance's rows and columns, in order (empty without a fit).
    no_parameters : ndarray of bool or None
        Per band, True where the band centre lies in one of the class's ``bad_bands``: the class
        has no parameters there (``params`` and ``covariance`` are NaN in those bands) and the
        correction passes the band through uncorrected. None when no band is bad.
    """

    id: int
    name: str
    model: Model
    params: dict[str, np.ndarray]
    covariance: np.ndarray | None = None
    covariance_names: tuple[str, ...] = ()
    no_parameters: np.ndarray | None = None


def class_label(entry: ClassFields) -> str:
    """``"class 2 (grass)"``, the prefix of every message about a class (a long or unprintable
    name shortened)."""
    name = entry.name if len(entry.name) <= 60 and entry.name.isprintable() else short_repr(entry.name, 60)
    return f"class {entry.id} ({name})"


def _band_count(entry: ClassFields, wavelengths: Sequence[float] | None, n_bands: int | None) -> int:
    if n_bands is None:
        if wavelengths is None:
            raise ParameterError(f"{class_label(entry)}: give the image's wavelengths or number of bands")
        n_bands = len(wavelengths)
    return n_bands


def in_ranges(centres: Sequence[float], ranges: Sequence[Sequence[float]]) -> np.ndarray:
    """Which of the band ``centres`` [nm] lie in any of ``ranges`` (``[low, high]`` [nm], ends
    included): a bool array shaped like ``centres``."""
    values = np.asarray(centres, dtype=float)
    inside = np.zeros(values.shape, dtype=np.bool_)
    for low, high in ranges:
        inside = inside | ((values >= low) & (values <= high))
    return inside


def check_bad_bands(entry: ClassFields) -> None:
    """Raise ``ValueError`` (in a pydantic validator) unless each of ``entry.bad_bands`` is a finite
    range ``0 < low <= high`` [nm] that holds none of the class's own ``wavelengths``."""
    for low, high in entry.bad_bands or ():
        if not (np.isfinite(low) and np.isfinite(high) and 0 < low <= high):
            raise ValueError(f"{class_label(entry)}: bad_bands range [{low:g}, {high:g}] nm must be finite with "
                             "0 < low <= high")
    if entry.wavelengths is not None:
        inside = np.asarray(entry.wavelengths, dtype=float)[in_ranges(entry.wavelengths, entry.bad_bands or ())]
        if inside.size:
            raise ValueError(f"{class_label(entry)}: wavelength {inside[0]:g} nm lies in bad_bands, where the "
                             "class has no parameters; leave it out of wavelengths and params, or out of bad_bands")


def no_parameter_bands(entry: ClassFields, wavelengths: Sequence[float] | None) -> np.ndarray | None:
    """Per image band, whether its centre lies in one of ``entry.bad_bands`` (None where none does)."""
    if not entry.bad_bands:
        return None
    if wavelengths is None:
        raise ParameterError(
            f"{class_label(entry)}: bad_bands are wavelength ranges [nm]; the image's band wavelengths are needed "
            f"(a 'wavelength' coordinate or tag, band descriptions, or {option('wavelengths')})"
        )
    bad = in_ranges(wavelengths, entry.bad_bands)
    return bad if bad.any() else None


def _with_gaps(good_values: np.ndarray, bad: np.ndarray | None) -> np.ndarray:
    """Values at the good bands spread to every band, NaN at the ``bad`` ones."""
    if bad is None:
        return good_values
    values = np.full(bad.shape + good_values.shape[1:], np.nan)
    values[~bad] = good_values
    return values


def band_values(entry: ClassFields, wavelengths: Sequence[float] | None, n_bands: int | None,
                extrapolate: bool) -> dict[str, np.ndarray]:
    """The parameters of ``entry`` at the image's bands (:meth:`ClassEntry.band_values`); NaN in
    the bands of its ``bad_bands``, which are not interpolated (nor checked against the range of
    its wavelengths)."""
    n_bands = _band_count(entry, wavelengths, n_bands)
    if wavelengths is not None and len(wavelengths) != n_bands:
        raise ParameterError(
            f"{len(wavelengths)} band wavelengths given for an image of {n_bands} bands"
        )
    bad = no_parameter_bands(entry, wavelengths)
    good_centres = wavelengths if bad is None else np.asarray(wavelengths, dtype=float)[~bad]
    values: dict[str, np.ndarray] = {}
    for name in get_model(entry.model).parameter_names:
        value = entry.params[name]
        if not isinstance(value, list):
            values[name] = np.full(n_bands, float(value))
        elif entry.wavelengths is not None:
            values[name] = _with_gaps(interpolate(entry, name, np.asarray(value, float), good_centres, extrapolate),
                                      bad)
        elif len(value) != n_bands:
            raise ParameterError(
                f"{class_label(entry)}: parameter {name} has {len(value)} per-band values but the image "
                f"has {n_bands} bands"
            )
        else:
            values[name] = np.asarray(value, dtype=float)
    if bad is not None:  # no parameters in the bad bands: NaN, never a number to apply
        values = {name: np.where(bad, np.nan, value) for name, value in values.items()}
    try:  # linear interpolation stays within the bounds, but check what the kernels will see
        checked = values if bad is None else {name: value[~bad] for name, value in values.items()}
        get_model(entry.model).validate(checked)
    except ParameterError as error:
        raise ParameterError(f"{class_label(entry)}: {error}") from None
    return values


def band_covariance(entry: ClassFields, wavelengths: Sequence[float] | None, n_bands: int | None,
                    extrapolate: bool) -> np.ndarray | None:
    """The ``fit:`` covariance of ``entry`` at the image's bands (:meth:`ClassEntry.band_covariance`)."""
    if entry.fit is None:
        return None
    n_bands = _band_count(entry, wavelengths, n_bands)
    matrices = entry.fit.matrices()
    bad = no_parameter_bands(entry, wavelengths)
    if not entry.fit.per_wavelength:
        resolved = np.repeat(matrices, n_bands, axis=0)
    elif entry.wavelengths is None:
        if matrices.shape[0] != n_bands:
            raise ParameterError(
                f"{class_label(entry)}: fit.covariance has {matrices.shape[0]} per-band matrices but the "
                f"image has {n_bands} bands"
            )
        resolved = matrices.copy()
    else:
        p = matrices.shape[1]
        flat = matrices.reshape(matrices.shape[0], p * p)
        centres = wavelengths if bad is None else np.asarray(wavelengths, dtype=float)[~bad]
        columns = [interpolate(entry, "fit.covariance", flat[:, j], centres, extrapolate) for j in range(p * p)]
        resolved = np.stack(columns, axis=-1).reshape(len(columns[0]), p, p)
        resolved = _with_gaps(0.5 * (resolved + np.swapaxes(resolved, 1, 2)), bad)  # symmetric to the last bit
    if bad is not None:
        resolved[bad] = np.nan
    return resolved


def interpolate(entry: ClassFields, name: str, value: np.ndarray, wavelengths: Sequence[float] | None,
                extrapolate: bool) -> np.ndarray:
    """``value`` (one number per wavelength of ``entry``) at the band centres ``wavelengths``."""
    if wavelengths is None:
        raise ParameterError(
            f"{class_label(entry)}: parameter {name} is given per wavelength; the image's band "
            f"wavelengths are needed (a 'wavelength' coordinate or tag, band descriptions, or {option('wavelengths')})"
        )
    table = np.asarray(entry.wavelengths, dtype=float)
    centres = np.asarray(wavelengths, dtype=float)
    if not np.all(np.isfinite(centres)):
        raise ParameterError("band wavelengths must be finite numbers [nm]")
    outside = (centres < table[0]) | (centres > table[-1])
    if np.any(outside) and not extrapolate:
        raise ParameterError(
            f"{class_label(entry)}: parameter {name}: band centre {centres[outside][0]:g} nm is outside "
            f"the table's wavelengths [{table[0]:g}, {table[-1]:g}] nm ({int(np.sum(outside))} band(s)); "
            f"{option('extrapolate')} gives them the edge values"
        )
    return np.interp(centres, table, value)  # holds the edge values outside the range


def resolve_entry(entry: ClassFields, wavelengths: Sequence[float] | None, n_bands: int | None,
                  extrapolate: bool) -> BandParameters:
    """``entry``'s model, parameters and covariance at the image's bands."""
    return BandParameters(
        entry.id, entry.name, get_model(entry.model),
        band_values(entry, wavelengths, n_bands, extrapolate),
        band_covariance(entry, wavelengths, n_bands, extrapolate),
        tuple(entry.fit.parameters) if entry.fit is not None else (),
        no_parameter_bands(entry, wavelengths),
    )


def material_caveat(entry: ClassFields, wavelengths: Sequence[float] | None) -> str | None:
    """Why ``entry`` may not fit the image's bands, or None (:meth:`ClassEntry.wavelength_caveat`)."""
    if entry.material is None or wavelengths is None or len(wavelengths) == 0:
        return None
    source = load_material(entry.material).wavelength
    centres = np.asarray(wavelengths, dtype=float)
    distance = np.abs(centres - source)
    if not np.nanmax(distance) > MATERIAL_WAVELENGTH_TOLERANCE:  # NaN band centres: nothing known
        return None
    return (
        f"{class_label(entry)}: material {entry.material} is a fit at {source:g} nm, applied unchanged to bands "
        f"{np.nanmin(centres):g}-{np.nanmax(centres):g} nm (up to {np.nanmax(distance):g} nm away); "
        "a table fitted per band (brdfcorr fit-classes) suits such bands better"
    )


def bands_dataset(
    resolved: Mapping[int, BandParameters],
    wavelengths: Sequence[float] | None = None,
    n_bands: int | None = None,
) -> xr.Dataset:
    """Classes resolved to the bands as a Dataset of (class, band) arrays
    (:meth:`ParameterTable.to_xarray`)."""
    import xarray as xr

    if n_bands is None:
        n_bands = len(wavelengths) if wavelengths is not None else 0
    names = list(dict.fromkeys(n for entry in resolved.values() for n in entry.params))
    variables = {}
    for name in names:
        data = np.full((len(resolved), n_bands), np.nan)
        for row, entry in enumerate(resolved.values()):
            if name in entry.params:
                data[row] = entry.params[name]
        units = next(
            e.model.parameter(name).units for e in resolved.values() if name in e.params
        )
        variables[name] = (("class", "band"), data, {"units": units})
    coords: dict[str, Any] = {
        "class": ("class", np.array(list(resolved), dtype=np.int64)),
        "name": ("class", [entry.name for entry in resolved.values()]),
        "model": ("class", [entry.model.name for entry in resolved.values()]),
        "band": ("band", np.arange(1, n_bands + 1)),
    }
    if wavelengths is not None:
        coords["wavelength"] = ("band", np.asarray(wavelengths, float), {"units": "nm"})
    return xr.Dataset(variables, coords=coords, attrs={"long_name": "BRDF parameter table"})
