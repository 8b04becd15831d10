"""Goniometer measurement tables: read, validate, filter and write them (synthetic ones:
:mod:`brdfcorr.fit.synthetic`).

A measurement table is a CSV file with one BRDF measurement per row and a header naming the
columns (any order, case-insensitive; a unit suffix such as ``theta_i [deg]`` must name the unit
brdfcorr reads, below, else the table is refused: ``theta_i [rad]`` would be read as degrees;
extra columns are ignored, ``#`` lines are comments)::

    theta_i,theta_r,phi,brdf,sigma
    30,0,180,0.0262,0.0010
    30,5,180,0.0266,0.0011

=========  =====================================================  ==============================
column     meaning                                                domain
=========  =====================================================  ==============================
theta_i    illumination (lamp/sun) zenith angle [deg]             [0, 90)
theta_r    view (sensor) zenith angle [deg]                       [0, 90)
phi        relative azimuth [deg], 180 = forward scattering       [0, 180]
brdf       measured BRDF [sr^-1]                                  finite, >= 0
sigma      optional 1-sigma error of ``brdf`` [sr^-1]             finite, > 0
wavelength optional wavelength of the measurement [nm]            finite, >= 100
=========  =====================================================  ==============================

A table with a ``wavelength`` column holds several spectral bands of the same geometries (the EGO
spectroradiometer measured 425-975 nm); :meth:`Measurements.at_wavelength` selects one.

The angle conventions are those of ``docs/conventions.md`` (:mod:`brdfcorr.geometry`). Every check reports
all offending rows of a column at once, by their line number in the file, in a single
:class:`~brdfcorr.errors.MeasurementError`.

References
----------
.. [1] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII: 122-145 EGO goniometer measurements a
   sample at theta_i = 30, 50, 65 deg, principal plane and azimuthal cuts, relative azimuth >= 90
   deg fitted, total errors 4-15 %.
"""

from __future__ import annotations

import csv
import math
import os
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdfcorr.errors import BrdfcorrWarning, MeasurementError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.io.files import atomic_path

__all__ = [
    "REQUIRED_COLUMNS",
    "Measurements",
    "check_measurements",
    "read_measurements",
    "write_measurements",
    "filter_measurements",
    "selection_mask",
    "MeasurementSelection",
]

REQUIRED_COLUMNS = ("theta_i", "theta_r", "phi", "brdf")
OPTIONAL_COLUMNS = ("sigma", "wavelength")
#: Column names (besides ``wavelength...``) that name the bands of a multi-band file.
_BANDS = frozenset({"lambda", "wl", "band", "bands", "channel"})
#: Shortest wavelength [nm] a measurement table may hold: below lie micrometres (0.4-2.5), not the
#: optical remote-sensing range.
MIN_WAVELENGTH = 100.0

#: How many offending rows an error message lists before it says "and N more".
_MAX_LISTED = 5

# A header cell "theta_i [deg]" or "brdf (1/sr)" names the column theta_i / brdf, in that unit.
_UNIT_SUFFIX = re.compile(r"\s*[\[(](.*)[\])]\s*$")
#: The units a header may name for each column (lower case, spaces removed): the ones brdfcorr reads.
_UNITS = {
    **dict.fromkeys(("theta_i", "theta_r", "phi"), {"deg", "degree", "degrees", "°"}),
    **dict.fromkeys(("brdf", "sigma"), {"1/sr", "sr^-1", "sr-1", "sr⁻¹", "/sr", "sr**-1", "1/steradian"}),
    "wavelength": {"nm", "nanometer", "nanometers", "nanometre", "nanometres"},
}


@dataclass(frozen=True, eq=False)
class Measurements:
    """A validated set of BRDF measurements (1-D float arrays of equal length).

    Build it with :func:`read_measurements`, :func:`synthesize_measurements` or directly from
    arrays; the constructor validates (see :func:`check_measurements`).

    Attributes
    ----------
    theta_i, theta_r : numpy.ndarray
        Illumination and view zenith angles [deg], in [0, 90).
    phi : numpy.ndarray
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.
    brdf : numpy.ndarray
        Measured BRDF [sr^-1], >= 0.
    sigma : numpy.ndarray or None
        1-sigma measurement errors of ``brdf`` [sr^-1], > 0; None when the table has none.
    rows : numpy.ndarray of int or None
        Line numbers of the measurements in their file (the header is line 1), for messages;
        None for measurements that do not come from a file.
    source : str
        The file the measurements come from, or a description.
    filters : tuple of str
        The selections applied so far (``"phi >= 90"``), for reports.
    wavelength : numpy.ndarray or None
        Wavelength of each measurement [nm], > 0; None when the table has no such column.
    """

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    brdf: np.ndarray
    sigma: np.ndarray | None = None
    rows: np.ndarray | None = None
    source: str = "measurements"
    filters: tuple[str, ...] = field(default=())
    wavelength: np.ndarray | None = None

    def __post_init__(self):
        labels = None if self.rows is None else [f"line {row}" for row in self.rows]
        checked = check_measurements(
            self.theta_i, self.theta_r, self.phi, self.brdf, self.sigma,
            source=self.source, labels=labels,
        )
        for name, values in zip(("theta_i", "theta_r", "phi", "brdf", "sigma"), checked):
            object.__setattr__(self, name, values)
        if self.rows is not None:
            object.__setattr__(self, "rows", np.asarray(self.rows, dtype=int))
        if self.wavelength is not None:
            wavelength = np.broadcast_to(np.asarray(self.wavelength, dtype=float), self.brdf.shape)
            invalid = ~(np.isfinite(wavelength) & (wavelength > 0))
            labels = labels or [f"index {index}" for index in range(wavelength.size)]
            if invalid.any():
                raise MeasurementError(
                    f"{self.source}: wavelength not finite and positive at {_list_rows(labels, invalid)}"
                )
            short = wavelength < MIN_WAVELENGTH  # a column in micrometres, or part of one
            if short.any():
                raise MeasurementError(
                    f"{self.source}: wavelength below {MIN_WAVELENGTH:g} nm at {_list_rows(labels, short)} "
                    f"(e.g. {wavelength.min():g}): micrometres? Wavelengths are in nm (x 1000)")
            object.__setattr__(self, "wavelength", wavelength.copy())

    @property
    def wavelengths(self) -> tuple[float, ...]:
        """The distinct wavelengths [nm], increasing; empty without a wavelength column."""
        return () if self.wavelength is None else tuple(map(float, np.unique(self.wavelength)))

    def at_wavelength(self, wavelength: float) -> Measurements:
        """The measurements at one wavelength [nm] (an error naming the available ones if absent)."""
        if self.wavelength is None:
            raise MeasurementError(f"{self.source}: no wavelength column to select {wavelength:g} nm from")
        keep = self.wavelength == wavelength
        if not keep.any():
            available = ", ".join(f"{value:.10g}" for value in self.wavelengths)
            raise MeasurementError(
                f"{self.source}: no measurements at {wavelength:.10g} nm; wavelengths: {available}"
            )
        return self.select(keep, f"wavelength = {wavelength:.10g} nm")

    def __len__(self) -> int:
        return self.brdf.size

    @property
    def geometry(self) -> ScatteringGeometry:
        """The :class:`~brdfcorr.geometry.ScatteringGeometry` of all measurements."""
        return ScatteringGeometry(self.theta_i, self.theta_r, self.phi)

    def select(self, mask, description: str | None = None) -> Measurements:
        """The measurements where the boolean ``mask`` is True (a new object)."""
        mask = np.asarray(mask, dtype=bool)
        return Measurements(
            theta_i=self.theta_i[mask],
            theta_r=self.theta_r[mask],
            phi=self.phi[mask],
            brdf=self.brdf[mask],
            sigma=None if self.sigma is None else self.sigma[mask],
            rows=None if self.rows is None else self.rows[mask],
            source=self.source,
            filters=self.filters + ((description,) if description else ()),
            wavelength=None if self.wavelength is None else self.wavelength[mask],
        )


def _list_rows(labels: Sequence[str], where: np.ndarray) -> str:
    listed = [labels[index] for index in np.flatnonzero(where)[:_MAX_LISTED]]
    more = int(np.count_nonzero(where)) - len(listed)
    text = ", ".join(listed)
    return f"{text} and {more} more" if more > 0 else text


def check_measurements(
    theta_i, theta_r, phi, brdf, sigma=None, *, source: str = "measurements", labels=None
):
    """Validate measurement arrays; return them as equal-length 1-D float arrays.

    Parameters
    ----------
    theta_i, theta_r : array-like
        Illumination and view zenith angles [deg]; must be finite and in [0, 90).
    phi : array-like
        Relative azimuth [deg]; must be finite and in [0, 180] (fold first with
        :func:`brdfcorr.geometry.relative_azimuth`).
    brdf : array-like
        Measured BRDF [sr^-1]; must be finite and >= 0.
    sigma : array-like or None
        1-sigma errors of ``brdf`` [sr^-1]; must be finite and > 0.
    source : str
        Name of the data set, the first word of any message (a file name).
    labels : sequence of str, optional
        How to name each row in messages (``"line 7"``); default ``"index 0"``, ...

    Returns
    -------
    tuple of numpy.ndarray
        ``(theta_i, theta_r, phi, brdf, sigma)`` broadcast to one 1-D shape (sigma may be None).

    Raises
    ------
    brdfcorr.errors.MeasurementError
        One message listing, per column, the offending rows and why.
    """
    arrays = {"theta_i": theta_i, "theta_r": theta_r, "phi": phi, "brdf": brdf}
    if sigma is not None:
        arrays["sigma"] = sigma
    try:
        converted = {name: np.asarray(value, dtype=float) for name, value in arrays.items()}
    except (TypeError, ValueError):
        bad = next(
            name for name, value in arrays.items() if not _is_numeric(value)
        )
        raise MeasurementError(f"{source}: column {bad} holds non-numeric values") from None
    try:
        broadcast = np.broadcast_arrays(*converted.values())
    except ValueError:
        shapes = ", ".join(f"{name} {value.shape}" for name, value in converted.items())
        raise MeasurementError(f"{source}: arrays of different shapes: {shapes}") from None
    values = {name: np.ravel(array).copy() for name, array in zip(converted, broadcast)}
    size = values["brdf"].size
    if size == 0:
        raise MeasurementError(f"{source}: no measurements")
    if labels is None:
        labels = [f"index {index}" for index in range(size)]

    problems = [problem for name, array in values.items() for problem in _column_problems(name, array, labels)]
    if problems:
        raise MeasurementError(f"{source}: " + "; ".join(problems))
    _refuse_radians(values, source)
    return tuple(values.get(name) for name in ("theta_i", "theta_r", "phi", "brdf", "sigma"))


def _refuse_radians(values: dict[str, np.ndarray], source: str) -> None:
    """Refuse angles that can only be radians: every zenith below 1.6 (pi/2), with the largest
    beyond 0.2 or the relative azimuths reaching beyond 1 but not beyond 3.15 (pi). In degrees
    that would be a goniometer that never left the zenith by 1.6 deg; read so, a fit in radians
    gave parameters far off (w 0.77 deg^-1 for 0.037) with only an identifiability warning. (Zeniths
    of a few tenths of a degree at most, in the plane of incidence, stay degrees.)"""
    zeniths = np.concatenate([values["theta_i"], values["theta_r"]])
    highest, phi = zeniths.max(), values["phi"].max()
    if highest < 1.6 and (highest > 0.2 or 1.0 < phi <= 3.15):
        raise MeasurementError(
            f"{source}: the angles look like radians (theta_i, theta_r up to {highest:.3g}, phi up to "
            f"{phi:.3g}); brdfcorr needs degrees (numpy.degrees converts them)")
    # phi in radians beside zeniths in degrees: the forward rows (pi) were read as phi = 3.1 deg,
    # backscatter (f_vol 0.003 for 0.02, without a word). Radians of a goniometer's azimuth steps
    # are no multiples of half a degree; a hotspot scan in degrees (phi 0, 0.5, ... 3) is.
    steps = values["phi"] * 2.0
    if highest >= 10.0 and 1.0 < phi <= 2 * math.pi + 0.01 and np.any(np.abs(steps - np.round(steps)) > 1e-6):
        raise MeasurementError(
            f"{source}: phi looks like radians (every value within [0, 2 pi], up to {phi:.3g}, not on half degrees) "
            f"beside zeniths in degrees (up to {highest:.3g}); brdfcorr needs degrees (numpy.degrees converts them)")


def _column_problems(name: str, array: np.ndarray, labels) -> list[str]:
    """What is wrong with one measurement column, naming the rows: NaN or infinite values, angles
    outside their domain [deg] (zeniths [0, 90), azimuth [0, 180]), a negative BRDF or a
    non-positive sigma [sr^-1]."""
    problems = []
    finite = np.isfinite(array)
    if not finite.all():
        problems.append(f"{name} is NaN or infinite at {_list_rows(labels, ~finite)}")
    with np.errstate(invalid="ignore"):
        if name in ("theta_i", "theta_r"):
            invalid, rule = (array < 0) | (array >= 90), "outside [0, 90) deg"
        elif name == "phi":
            invalid, rule = (array < 0) | (array > 180), "outside [0, 180] deg"
        elif name == "brdf":
            invalid, rule = array < 0, "negative"
        else:
            invalid, rule = array <= 0, "not positive"
    invalid &= finite
    if invalid.any():
        problems.append(f"{name} {rule} at {_list_rows(labels, invalid)}")
    return problems


def _is_numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


def _column_name(header_cell: str) -> str:
    return _UNIT_SUFFIX.sub("", header_cell.strip()).strip().lower()


def _check_units(cells: list[str], header: list[str], path: Path) -> None:
    """MeasurementError for a column whose header names a unit other than the one brdfcorr reads
    (``theta_i [rad]``, ``brdf [%]``): its values would be read in the wrong unit."""
    for cell, name in zip(cells, header):
        match = _UNIT_SUFFIX.search(cell.strip())
        written = "" if match is None else match[1].strip()
        if name in _UNITS and written and re.sub(r"\s+", "", written).lower() not in _UNITS[name]:
            raise MeasurementError(
                f"{path}: column {name} is in {written!r}; brdfcorr reads angles in degrees, brdf and sigma in "
                "sr^-1 and wavelengths in nm: convert the column (and its header)"
            )


def _read_text(path: Path) -> str:
    """The CSV's text; MeasurementError for a missing, non-regular, binary or unreadable file."""
    if path.exists() and not (path.is_file() or path.is_dir()):  # a FIFO or device would block or never end
        raise MeasurementError(f"{path}: not a regular file")
    try:
        text = path.read_text(encoding="utf-8-sig")  # utf-8-sig drops a spreadsheet's BOM
    except FileNotFoundError:
        raise MeasurementError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise MeasurementError(f"{path}: is a directory, not a CSV file") from None
    except UnicodeDecodeError:
        raise MeasurementError(f"{path}: not a UTF-8 text (CSV) file") from None
    except OSError as error:
        raise MeasurementError(f"{path}: cannot read: {error.strerror}") from None
    return text


def _checked_header(cells: list[str], path: Path, line: int) -> list[str]:
    """The column names of the header cells (units in brackets dropped, lower case); MeasurementError
    for a duplicated or missing required column (``line``: the header's line number)."""
    header = [_column_name(cell) for cell in cells]
    _check_units(cells, header, path)
    duplicated = sorted({name for name in header if name and header.count(name) > 1})
    if duplicated:
        raise MeasurementError(f"{path}: duplicated column(s) {', '.join(duplicated)}")
    missing = [name for name in REQUIRED_COLUMNS if name not in header]
    if missing:
        raise MeasurementError(
            f"{path}: missing column(s) {', '.join(missing)} (line {line} has "
            f"{', '.join(header) or 'no names'}; required: {', '.join(REQUIRED_COLUMNS)}"
            f"[, {', '.join(OPTIONAL_COLUMNS)}])"
        )
    return header


def _refuse_unread_bands(header: list[str], body: list[list[str]], path: Path) -> None:
    """Refuse a column that names several bands (``wavelength_nm``, ``band``, ``lambda`` with more
    than one value) beside no ``wavelength`` column: it is not read, and every band was pooled
    into one fit without a word (errors sqrt(3) too small for three). One value is one band."""
    if "wavelength" in header:
        return
    for index, name in enumerate(header):
        if (name.startswith("wavelength") or name in _BANDS) and len({row[index].strip() for row in body}) > 1:
            raise MeasurementError(f"{path}: column {name!r} holds several bands; name the band centres [nm] "
                                   "'wavelength' (one fit per band), or give one band per file")


def _parsed_column(name: str, cells: list[str], labels: list[str]) -> tuple[np.ndarray, str | None]:
    """A column's cells as floats (unparsable ones left unset), and what is wrong with them (the rows
    that are not numbers, with the first such cell) or None."""
    values = np.empty(len(cells))
    unparsable = np.zeros(len(cells), dtype=bool)
    for index, cell in enumerate(cells):
        try:
            values[index] = float(cell)
        except ValueError:
            unparsable[index] = True
    if not unparsable.any():
        return values, None
    first = cells[int(np.flatnonzero(unparsable)[0])]
    return values, f"column {name} is not a number at {_list_rows(labels, unparsable)} (e.g. {first!r})"


def read_measurements(path: str | os.PathLike) -> Measurements:
    """Read and validate a measurement CSV table (columns ``theta_i, theta_r, phi, brdf[, sigma]``).

    Parameters
    ----------
    path : path-like
        The CSV file. Comma-separated, a header line first; blank lines and lines starting with
        ``#`` are skipped. Angles in degrees, BRDF and sigma in sr^-1, an optional wavelength
        column in nm. The file is only read.

    Returns
    -------
    Measurements
        With ``rows`` holding each measurement's line number in the file.

    Raises
    ------
    brdfcorr.errors.MeasurementError
        For an unreadable file, a missing or duplicated column, rows with a wrong number of
        fields, non-numeric or empty cells, angles outside their domain, a negative or NaN BRDF or a
        non-positive sigma. The message names the file, the column and the lines.
    """
    path = Path(path)
    text = _read_text(path)

    numbered = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not numbered:
        raise MeasurementError(f"{path}: empty file; expected a header {','.join(REQUIRED_COLUMNS)}")
    records = list(csv.reader(line for _, line in numbered))
    header = _checked_header(records[0], path, numbered[0][0])
    body, numbers = records[1:], [number for number, _ in numbered[1:]]
    if not body:
        raise MeasurementError(f"{path}: no measurements after the header")
    labels = [f"line {number}" for number in numbers]
    ragged = np.array([len(record) != len(header) for record in body])
    if ragged.any():
        raise MeasurementError(
            f"{path}: expected {len(header)} fields, as in the header, at {_list_rows(labels, ragged)}"
        )

    _refuse_unread_bands(header, body, path)
    wanted = [name for name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if name in header]
    columns, problems = {}, []
    for name in wanted:
        columns[name], problem = _parsed_column(name, [record[header.index(name)].strip() for record in body], labels)
        problems += [problem] if problem else []
    if problems:
        raise MeasurementError(f"{path}: " + "; ".join(problems))
    _warn_repeated_rows(np.column_stack(list(columns.values())), labels, path)
    return Measurements(**columns, rows=np.array(numbers), source=str(path))


def _warn_repeated_rows(table: np.ndarray, labels: list[str], path: Path) -> None:
    """A :class:`~brdfcorr.errors.BrdfcorrWarning` naming the rows that repeat an earlier row in
    every column: a fit counts them as measurements of their own, which shrinks its errors (two
    copies of every row by sqrt(2)); a repeated measurement differs at least in its BRDF."""
    _, first = np.unique(table, axis=0, return_index=True)
    repeated = np.ones(len(table), dtype=bool)
    repeated[first] = False
    if repeated.any():
        warnings.warn(f"{path}: the rows at {_list_rows(labels, repeated)} repeat earlier ones in every column: "
                      "a fit counts them as measurements of their own and its errors shrink; remove them if they "
                      "are copies", BrdfcorrWarning, stacklevel=3)


def write_measurements(path: str | os.PathLike, measurements: Measurements) -> Path:
    """Write measurements as a CSV table that :func:`read_measurements` reads back.

    Values are written with 10 significant digits. The file appears complete or not at all
    (written to a temporary name, renamed when complete). Returns the path.
    """
    path = Path(path)
    names = list(REQUIRED_COLUMNS) + [
        name for name in OPTIONAL_COLUMNS if getattr(measurements, name) is not None
    ]
    columns = [getattr(measurements, name) for name in names]
    with atomic_path(path) as temporary:
        with open(temporary, "w", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            writer.writerow(names)
            writer.writerows([f"{value:.10g}" for value in row] for row in zip(*columns))
    return path


def selection_mask(
    measurements: Measurements,
    *,
    min_phi: float | None = None,
    max_phi: float | None = None,
    max_zenith: float | None = None,
) -> tuple[np.ndarray, str]:
    """The rows kept by a geometric selection, and its description (``"phi >= 90"``).

    See :func:`filter_measurements` for the parameters; an empty description means no selection.
    """
    keep = np.ones(len(measurements), dtype=bool)
    applied = []
    # At a zenith of 0 the relative azimuth is undefined (every model is the same for any phi): an
    # azimuth selection keeps such rows whatever phi they were written with.
    undefined = (measurements.theta_i == 0) | (measurements.theta_r == 0)
    if min_phi is not None:
        keep &= undefined | (measurements.phi >= min_phi)
        applied.append(f"phi >= {min_phi:g}")
    if max_phi is not None:
        keep &= undefined | (measurements.phi <= max_phi)
        applied.append(f"phi <= {max_phi:g}")
    if max_zenith is not None:
        keep &= (measurements.theta_i <= max_zenith) & (measurements.theta_r <= max_zenith)
        applied.append(f"theta_i, theta_r <= {max_zenith:g}")
    return keep, " and ".join(applied)


def filter_measurements(
    measurements: Measurements,
    *,
    min_phi: float | None = None,
    max_phi: float | None = None,
    max_zenith: float | None = None,
) -> Measurements:
    """Select measurements by geometry, e.g. only ``phi >= 90`` as paper 003 fitted [1]_.

    Parameters
    ----------
    measurements : Measurements
    min_phi, max_phi : float, optional
        Keep only relative azimuths in ``[min_phi, max_phi]`` [deg] (and the rows at a zenith of 0,
        whose azimuth is undefined).
    max_zenith : float, optional
        Keep only measurements with both theta_i and theta_r <= ``max_zenith`` [deg] (paper 003,
        section 5: the simplified model is safe up to 70 deg).

    Returns
    -------
    Measurements
        The selected rows; ``filters`` records the selection.

    Raises
    ------
    brdfcorr.errors.MeasurementError
        If no measurement is left.
    """
    keep, description = selection_mask(
        measurements, min_phi=min_phi, max_phi=max_phi, max_zenith=max_zenith
    )
    if not description:
        return measurements
    azimuthal = (measurements.theta_i > 0) & (measurements.theta_r > 0)  # the rows a phi selection chooses
    if not keep.any() or (not (keep & azimuthal).any() and (min_phi, max_phi) != (None, None)):
        raise MeasurementError(
            f"{measurements.source}: no measurement has {description} "
            f"(of {len(measurements)} measurements)"
        )
    return measurements.select(keep, description)


@dataclass(frozen=True)
class MeasurementSelection:
    """Which measurements of a table a fit uses; paper 003 fitted ``MeasurementSelection(min_phi=90)``.

    Attributes
    ----------
    min_phi, max_phi, max_zenith : float, optional
        The geometric selection of :func:`filter_measurements` [deg].
    wavelength : float, optional
        Only this wavelength [nm] of a table with a wavelength column
        (:meth:`Measurements.at_wavelength`).
    """

    min_phi: float | None = None
    max_phi: float | None = None
    max_zenith: float | None = None
    wavelength: float | None = None

    @property
    def geometry(self) -> dict[str, float | None]:
        """The keyword arguments of :func:`filter_measurements` and :func:`selection_mask`."""
        return {"min_phi": self.min_phi, "max_phi": self.max_phi, "max_zenith": self.max_zenith}
