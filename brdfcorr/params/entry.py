"""One class of a parameter table (:class:`ClassEntry`): its id, surface model and parameters,
checked against the model's registry, and their values at an image's bands.

A class given as a built-in ``material`` (:mod:`brdfcorr.models.materials`) takes the material's
model and parameters. The ``fit:`` record (:class:`~brdfcorr.params.fit_record.FitRecord`) and the
resolution to bands (:mod:`brdfcorr.params.bands`) are the modules below; the table of classes is
:mod:`brdfcorr.params.table`. Import the names from :mod:`brdfcorr.params`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated

import numpy as np
from pydantic import BeforeValidator, Field, model_validator

from brdfcorr._validation import Integer, Number, StrictModel, refuse_boolean, short_repr
from brdfcorr.errors import ParameterError, UnknownNameError
from brdfcorr.models import SURFACE_MODELS, Model, get_model
from brdfcorr.models.materials import load_material, material_names
from brdfcorr.params.bands import (
    MATERIAL_WAVELENGTH_TOLERANCE,
    band_covariance,
    band_values,
    check_bad_bands,
    class_label,
    material_caveat,
)
from brdfcorr.params.fit_record import FitRecord

__all__ = ["ClassEntry", "ParameterValue", "BandRange", "MATERIAL_WAVELENGTH_TOLERANCE"]


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
        for the other bands (:func:`brdfcorr.params.bands.band_values`).
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
        matrices, so still positive semi-definite), with the same edge-extrapolation rule. Between
        two table wavelengths this is an upper bound: the parameters interpolated with weights
        ``1 - w`` and ``w`` have the covariance ``(1-w)^2 S1 + w^2 S2 + w(1-w)(C + C^T)`` (C: the
        cross-covariance of the two wavelengths' fits, unknown to the table), largest where the
        fits' errors are fully correlated and never above ``(1-w) S1 + w S2``; fits of one sample at
        neighbouring wavelengths share its geometry and calibration errors, so independence (up to
        sqrt(2) smaller at the midpoint) is not assumed. Matrices
        given per band are taken as they are; a single matrix applies to every band. Rows and
        columns follow ``fit.parameters``.
        """
        return band_covariance(self, wavelengths, n_bands, extrapolate)
