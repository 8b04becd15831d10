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

The package's modules, from the bottom up: :mod:`~brdfcorr.params.fit_record` the ``fit:``
record and its checks, :mod:`~brdfcorr.params.bands` the resolution of a class to an image's bands
(:class:`BandParameters`, interpolation in wavelength), :mod:`~brdfcorr.params.entry` one class
(:class:`ClassEntry`), :mod:`~brdfcorr.params.table` the table, its reference geometry, its NDVI
interpolation and the file format. Import every name from here.
"""

from brdfcorr.params.bands import MATERIAL_WAVELENGTH_TOLERANCE as MATERIAL_WAVELENGTH_TOLERANCE
from brdfcorr.params.bands import BandParameters
from brdfcorr.params.bands import band_covariance as band_covariance
from brdfcorr.params.bands import band_values as band_values
from brdfcorr.params.bands import bands_dataset as bands_dataset
from brdfcorr.params.bands import check_bad_bands as check_bad_bands
from brdfcorr.params.bands import class_label as class_label
from brdfcorr.params.bands import in_ranges as in_ranges
from brdfcorr.params.bands import material_caveat as material_caveat
from brdfcorr.params.bands import resolve_entry as resolve_entry
from brdfcorr.params.entry import BandRange as BandRange
from brdfcorr.params.entry import ClassEntry
from brdfcorr.params.entry import ParameterValue as ParameterValue
from brdfcorr.params.fit_record import ERROR_TOLERANCE as ERROR_TOLERANCE
from brdfcorr.params.fit_record import Count as Count
from brdfcorr.params.fit_record import Covariance as Covariance
from brdfcorr.params.fit_record import FitRecord
from brdfcorr.params.fit_record import Statistic as Statistic
from brdfcorr.params.table import RADIANS_BELOW as RADIANS_BELOW
from brdfcorr.params.table import NdviInterpolation, ParameterTable, ReferenceGeometry, as_parameter_table, merge_tables
from brdfcorr.params.table import SunZenith as SunZenith
from brdfcorr.params.table import check_distinct_ids as check_distinct_ids

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
