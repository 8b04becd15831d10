"""Let pure numpy kernels take numpy, dask and xarray inputs and return the same kind.

The kernels in :mod:`brdfcorr.geometry` and :mod:`brdfcorr.models` are written with numpy ufuncs
and a few array functions (``np.clip``, ``np.where``), which dask dispatches lazily through the
``__array_ufunc__`` / ``__array_function__`` protocols. xarray objects are unwrapped with
:func:`xarray.apply_ufunc` (``dask="allowed"``), so dimensions are aligned by name, coordinates
are kept and dask-backed DataArrays stay lazy.

Neither xarray nor scipy is imported here until a call needs it: listing the models
(``brdfcorr models``) or reading a table imports this module and computes nothing.
"""

from __future__ import annotations

import functools
import inspect
import sys
from collections.abc import Callable

# Divisors that are positive on the open angle domain [0, 90) deg but reach 0 at its edge are
# floored with this, so that evaluating exactly at a grazing edge gives a finite number instead of
# a division warning.
TINY = 1e-300


# Sine and cosine of angles in degrees. scipy's versions reduce the argument in degrees, so they
# are exact at multiples of 90 deg (sin 180 = 0, not 1.2e-16): the facet inclination at grazing
# specular geometries (cos theta ~ 1e-16) depends on that.
@functools.cache
def _special():
    import scipy.special

    return scipy.special


def sind(angle):
    """``scipy.special.sindg``: the sine of an angle in degrees, exact at multiples of 90 deg."""
    return _special().sindg(angle)


def cosd(angle):
    """``scipy.special.cosdg``: the cosine of an angle in degrees, exact at multiples of 90 deg."""
    return _special().cosdg(angle)


def is_lazy(value) -> bool:
    """True for dask arrays and dask-backed xarray objects (values not to be touched)."""
    data = getattr(value, "data", value)
    return hasattr(data, "dask") or hasattr(value, "dask")


def apply_labelled(kernel: Callable, arguments: dict, name: str, units: str, long_name: str):
    """Call ``kernel(**arguments)``, unwrapping any xarray.DataArray arguments.

    Without DataArrays this is a plain call. With them, :func:`xarray.apply_ufunc` broadcasts the
    DataArrays by dimension name, passes their (numpy or dask) data to the kernel and wraps the
    result with the given ``name`` and ``units``/``long_name`` attrs (inputs' attrs are not
    copied: the units change). Other arguments are passed through unchanged.
    """
    xarray = sys.modules.get("xarray")  # no argument is a DataArray before xarray is imported
    labelled = [] if xarray is None else [key for key, value in arguments.items()
                                          if isinstance(value, xarray.DataArray)]
    if xarray is None or not labelled:
        return kernel(**arguments)

    def call(*values):
        return kernel(**{**arguments, **dict(zip(labelled, values))})

    result = xarray.apply_ufunc(
        call, *(arguments[key] for key in labelled), dask="allowed", keep_attrs=False
    )
    result.name = name
    result.attrs = {"units": units, "long_name": long_name}
    return result


def array_function(name: str, units: str, long_name: str) -> Callable:
    """Decorate a numpy/dask kernel so that it also accepts xarray arguments.

    Parameters
    ----------
    name, units, long_name :
        Metadata set on xarray outputs; see :func:`apply_labelled`.
    """

    def decorate(kernel: Callable) -> Callable:
        signature = inspect.signature(kernel)

        @functools.wraps(kernel)
        def wrapper(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            return apply_labelled(kernel, dict(bound.arguments), name, units, long_name)

        return wrapper

    return decorate
