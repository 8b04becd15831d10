"""The ``.brdf`` xarray accessor: notebook shortcuts that delegate to library functions.

>>> import brdfcorr  # registers the accessor
>>> corrected, qa = cube.brdf.normalize(classes, angles, table)  # doctest: +SKIP
>>> nbar, qa = stack.brdf.normalize(None, angles, "roy2017")  # (time, band, y, x)  # doctest: +SKIP
>>> fitted = stack.brdf.fit_classes(classes, angles)  # each pixel's own views  # doctest: +SKIP
>>> corrected, qa = stack.brdf.normalize(classes, angles, fitted.table)  # doctest: +SKIP

The accessor holds no state and no science: metadata lives in coords/attrs of the arrays.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import xarray as xr

if TYPE_CHECKING:
    from brdfcorr.correction import Normalized
    from brdfcorr.fit import ClassFitResult


__all__ = ["BrdfAccessor"]


@xr.register_dataarray_accessor("brdf")
class BrdfAccessor:
    """``DataArray.brdf``: BRDF operations on a reflectance cube (band, y, x) or a time series of
    them (time, band, y, x)."""

    def __init__(self, reflectance: xr.DataArray):
        self._reflectance = reflectance

    def normalize(self, classes, angles, params, reference=None, **options) -> Normalized:
        """:func:`brdfcorr.normalize` with this array as the reflectance (same arguments and checks):
        ``classes`` a class map or None (class 1 everywhere), ``angles`` a Dataset (or mapping)
        with ``sza``, ``saa``, ``vza``, ``vaa`` [deg], ``params`` a table, a table file or a
        built-in coefficient set's name (``"roy2017"``). A (time, band, y, x) cube is normalized
        date by date, lazily for dask."""
        from brdfcorr import correction  # at first use: `import brdfcorr` (and the CLI) need no dask

        return correction.normalize(self._reflectance, classes, angles, params, reference, **options)

    def fit_classes(self, classes, angles, models="ross_thick_li_sparse", **options) -> ClassFitResult:
        """:func:`brdfcorr.fit.fit_classes` with this array as the image: per-class, per-band
        parameters fitted from the imagery (``models`` a model name or
        :class:`brdfcorr.fit.ClassModels`). A (time, band, y, x) cube is fitted once over all its
        dates, with each pixel's level free by default (the shape from each pixel's own views,
        :mod:`brdfcorr.fit.within`); ``classes`` and ``angles`` per date (with ``time``) or for
        every date."""
        from brdfcorr import fit  # at first use, as normalize

        return fit.fit_classes(self._reflectance, classes, angles, models, **options)
