"""Built-in coefficient library: published global RTLSR kernel weights per spectral band.

The fixed-coefficient c-factor method (Roy et al. 2016, 2017; used by HLS, sen2nbar and FORCE)
normalizes Landsat and Sentinel-2 reflectance to nadir view with one set of Ross-Thick
Li-Sparse-Reciprocal weights per band, derived from a year of global MODIS BRDF retrievals. The
library (``brdfcorr/data/coefficients.yaml``) holds:

=========  ==========================================================================  ==============
name       source                                                                      bands
=========  ==========================================================================  ==============
roy2016    Roy et al. (2016), RSE 176, 255-271, Table 1                                blue ... swir2
roy2017    Roy et al. (2017), RSE 199, 25-38 (roy2016 + Sentinel-2 red-edge B5/B6/B7)  + red_edge_1-3
=========  ==========================================================================  ==============

Units: the published weights are reflectance factors (BRF = f_iso + f_vol K_vol + f_geo K_geo,
dimensionless). brdfcorr's ``ross_thick_li_sparse`` takes BRDF weights [sr^-1]
(BRDF = BRF / pi), so :meth:`CoefficientSet.params` divides by pi. The c-factor
``f(reference) / f(observed)`` is a ratio and does not change.

Example
-------
>>> from brdfcorr.models.coefficients import load_coefficients
>>> roy = load_coefficients("roy2016")
>>> roy.published["red"]["f_iso"]
0.169
>>> round(roy.params("red")["f_iso"], 5)            # sr^-1
0.05379
>>> roy.sensor_band("sentinel2", "B8A")
'nir'
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from importlib.resources import files

import yaml

from brdfcorr.errors import UnknownNameError
from brdfcorr.models._base import Model
from brdfcorr.models.registry import get_model

__all__ = ["CoefficientSet", "coefficient_names", "load_coefficients", "SENSORS"]

#: The sensors whose band names the library knows, and what they are.
SENSORS = {
    "sentinel2": "Sentinel-2 MSI (L1C/L2A band names B02 ... B12)",
    "landsat_oli": "Landsat 8/9 OLI (Collection 2 L2 SR_B2 ... SR_B7)",
    "landsat_tm_etm": "Landsat 4/5 TM and 7 ETM+ (Collection 2 L2 SR_B1 ... SR_B7)",
}


@dataclass(frozen=True)
class CoefficientSet:
    """A published set of RTLSR weights, one per spectral band.

    Attributes
    ----------
    name : str
        Library key (``"roy2016"``).
    label : str
        Human-readable name.
    model : Model
        The registered model the weights belong to (``ross_thick_li_sparse``).
    published : dict of str to dict of str to float
        Spectral band (``"blue"``, ``"red_edge_1"``, ...) -> ``f_iso``, ``f_vol``, ``f_geo`` as
        published: reflectance-factor weights (dimensionless).
    centres : dict of str to tuple of float
        Spectral band -> the lowest and highest nominal band centre [nm] of the sensor bands the
        weights were made for.
    sensor_bands : dict of str to dict of str to str
        Sensor (:data:`SENSORS`) -> its band names -> the spectral band whose weights they take.
    source : str
        Citation.
    """

    name: str
    label: str
    model: Model
    published: dict[str, dict[str, float]]
    centres: dict[str, tuple[float, float]]
    sensor_bands: dict[str, dict[str, str]]
    source: str

    def params(self, band: str) -> dict[str, float]:
        """The weights of spectral ``band`` as brdfcorr parameters: BRDF weights [sr^-1], the
        published reflectance-factor weights divided by pi (BRDF = BRF / pi)."""
        try:
            weights = self.published[band]
        except KeyError:
            raise UnknownNameError(
                f"{self.name}: no coefficients for spectral band {band!r}; it has {', '.join(self.published)}"
            ) from None
        return {key: value / math.pi for key, value in weights.items()}

    def sensor_band(self, sensor: str, band: str) -> str:
        """The spectral band whose weights ``sensor``'s band ``band`` takes (``"B8A"`` -> ``"nir"``)."""
        if sensor not in self.sensor_bands:
            raise UnknownNameError(f"unknown sensor {sensor!r}; known: {', '.join(self.sensor_bands)}")
        known = self.sensor_bands[sensor]
        if band not in known or known[band] not in self.published:
            usable = [name for name, spectral in known.items() if spectral in self.published]
            raise UnknownNameError(
                f"{self.name}: no coefficients for {sensor} band {band!r}; bands with coefficients: "
                f"{', '.join(usable)}"
            )
        return known[band]

    def wavelength_nodes(self) -> tuple[list[float], dict[str, list[float]]]:
        """Wavelengths [nm] and the weights [sr^-1] at them for a table interpolated in wavelength:
        each spectral band's lowest and highest centre carry its weights (one node where they
        coincide), so every sensor band of the library gets exactly its published weights."""
        nodes = sorted((centre, band) for band, pair in self.centres.items() for centre in sorted(set(pair)))
        values: dict[str, list[float]] = {key: [] for key in self.model.parameter_names}
        for _, band in nodes:
            for key, value in self.params(band).items():
                values[key].append(value)
        return [centre for centre, _ in nodes], values

    def table_entry(self, class_id: int = 1, *, sensor: str | None = None, bands: Sequence[str] | None = None,
                    name: str | None = None) -> dict:
        """The library as one class of a parameter table (:class:`brdfcorr.params.ClassEntry`).

        Parameters
        ----------
        class_id : int
            Class id of the entry (1 for a whole image without a class map).
        sensor, bands : optional
            A sensor (:data:`SENSORS`) and its band names in image order (``["B02", "B03"]``): one
            value per image band. Without them: the weights at :meth:`wavelength_nodes`, interpolated
            to the image's band centres by the table (a band between two spectral bands gets
            weights interpolated linearly in wavelength).
        name : str, optional
            Class name (default: the library name).
        """
        entry: dict = {"id": class_id, "name": name or self.name, "model": self.model.name}
        if bands is not None:
            if sensor is None:
                raise UnknownNameError(f"{self.name}: band names need their sensor ({', '.join(SENSORS)})")
            weights = [self.params(self.sensor_band(sensor, band)) for band in bands]
            entry["params"] = {key: [w[key] for w in weights] for key in self.model.parameter_names}
            return entry
        wavelengths, values = self.wavelength_nodes()
        entry.update(wavelengths=wavelengths, params=values)
        return entry

    def brdf(self, theta_i, theta_r, phi, band: str):
        """The BRDF [sr^-1] of spectral ``band`` at the given angles [deg] (numpy, dask or xarray)."""
        return self.model(theta_i, theta_r, phi, **self.params(band))


@cache
def _library() -> dict[str, CoefficientSet]:
    document = yaml.safe_load(files("brdfcorr").joinpath("data/coefficients.yaml").read_text())
    model = get_model(document["model"])
    sensors = {sensor: dict(bands) for sensor, bands in document["sensors"].items()}
    library = {}
    for name, entry in document["libraries"].items():
        published, centres = {}, {}
        for band, values in entry["bands"].items():
            published[band] = {key: float(values[key]) for key in model.parameter_names}
            low, high = (float(centre) for centre in values["centres"])
            centres[band] = (low, high)
        model.validate({key: [published[b][key] for b in published] for key in model.parameter_names})
        library[name] = CoefficientSet(name, entry["label"], model, published, centres, sensors,
                                       " ".join(entry["source"].split()))
    return library


def coefficient_names() -> tuple[str, ...]:
    """Names of the built-in coefficient sets."""
    return tuple(_library())


def load_coefficients(name: str) -> CoefficientSet:
    """The built-in :class:`CoefficientSet` called ``name`` (case-insensitive, e.g. ``"Roy2016"``)."""
    key = str(name).strip().lower().replace(" ", "").replace("-", "").replace("_", "")
    try:
        return _library()[key]
    except KeyError:
        raise UnknownNameError(
            f"unknown coefficient set {name!r}; built-in coefficient sets: {', '.join(coefficient_names())}"
        ) from None
