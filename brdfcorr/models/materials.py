"""Built-in material library: published BRDF model fits, loadable by name.

The library holds the Torrance-Sparrow fits of paper 003, Table 1 (550 nm, k fixed at 0.25), with
the 1-sigma errors and chi^2/dof the authors printed. Use a material directly as model parameters::

    >>> from brdfcorr.models.materials import load_material
    >>> tile = load_material("roof_tile")
    >>> tile.params["w"]
    0.0362
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib.resources import files

import yaml

from brdfcorr.errors import UnknownNameError
from brdfcorr.models._base import Model
from brdfcorr.models.registry import get_model

__all__ = ["Material", "load_material", "material_names"]


@dataclass(frozen=True)
class Material:
    """A published BRDF model fit of one material.

    Attributes
    ----------
    name : str
        Library key (``"roof_tile"``).
    label : str
        Human-readable name.
    model : Model
        The registered model the parameters belong to.
    params, errors : dict of str to float
        Fitted values and their published 1-sigma errors, in the model's units.
    wavelength : float
        Wavelength of the fit [nm].
    reduced_chi2 : float
        chi^2 per degree of freedom of the published fit.
    n_measurements : int or None
        Number of goniometer measurements fitted (None where the source does not say).
    source : str
        Citation.
    """

    name: str
    label: str
    model: Model
    params: dict[str, float]
    errors: dict[str, float]
    wavelength: float
    reduced_chi2: float
    n_measurements: int | None
    source: str

    def table_entry(self, class_id: int) -> dict:
        """The material as one class of a parameter table (band-independent parameters)."""
        return {"id": class_id, "name": self.name, "model": self.model.name, "params": dict(self.params)}

    def brdf(self, theta_i, theta_r, phi):
        """The material's BRDF [sr^-1] at the given angles [deg] (numpy, dask or xarray)."""
        return self.model(theta_i, theta_r, phi, **self.params)


@cache
def _library() -> dict[str, Material]:
    document = yaml.safe_load(files("brdfcorr").joinpath("data/materials.yaml").read_text())
    model = get_model(document["model"])
    return {
        name: Material(
            name=name,
            label=entry["label"],
            model=model,
            params=model.validate(entry["params"]),
            errors=dict(entry["errors"]),
            wavelength=float(document["wavelength"]),
            reduced_chi2=float(entry["reduced_chi2"]),
            n_measurements=entry["n_measurements"],
            source=" ".join(document["source"].split()),
        )
        for name, entry in document["materials"].items()
    }


def material_names() -> tuple[str, ...]:
    """Names of the built-in materials."""
    return tuple(_library())


def load_material(name: str) -> Material:
    """The built-in :class:`Material` called ``name``.

    Names are matched case-insensitively, with spaces and hyphens read as underscores
    (``"Roof tile"`` finds ``roof_tile``; ``"red_aluminum"`` finds ``red_aluminium``).
    """
    key = str(name).strip().lower().replace(" ", "_").replace("-", "_").replace("aluminum", "aluminium")
    try:
        return _library()[key]
    except KeyError:
        raise UnknownNameError(
            f"unknown material {name!r}; built-in materials: {', '.join(material_names())}"
        ) from None
