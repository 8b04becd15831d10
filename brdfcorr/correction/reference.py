"""The reference geometry of a correction, resolved once (:func:`resolve_reference`), and how
the factor limits are written in tags."""

from __future__ import annotations

import numpy as np

from brdfcorr.params import ParameterTable, ReferenceGeometry

__all__ = ["resolve_reference", "describe_limits", "scene_mean_sza", "fixed_sza"]


def resolve_reference(reference, params: ParameterTable) -> ReferenceGeometry:
    """The reference geometry to use: the given one (a dict is validated), else the table's, else
    the default (observed sun zenith, nadir view)."""
    if reference is None:
        return params.reference or ReferenceGeometry()
    if isinstance(reference, ReferenceGeometry):
        return reference
    validated = ParameterTable.from_dict({"reference": dict(reference)}, source="reference geometry").reference
    return validated if validated is not None else ReferenceGeometry()


def scene_mean_sza(sza, xp):
    """Mean of the valid solar zeniths (finite, in [0, 90)) [deg]; lazy for dask."""
    valid = (sza >= 0) & (sza < 90)
    return xp.nanmean(xp.where(valid, sza.astype(np.float64), np.nan))


def fixed_sza(reference: ReferenceGeometry) -> float:
    # "observed" takes the per-pixel sza inside the block; the scalar is then unused.
    return float(reference.sza) if not isinstance(reference.sza, str) else np.nan


def describe_limits(limits) -> str:
    return "none" if limits is None else f"{limits[0]:g},{limits[1]:g}"


