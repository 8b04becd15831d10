"""Benchmark: an urban line whose man-made classes have two lobes, corrected with tables fitted
from the imagery by ``--model auto``, by the two-lobe model itself, and by one-lobe models beside
them (issue 36; run by hand, not part of the test suite).

The scene is bench_kernels.py's scene B (a push-broom line flown north, view zenith -20..+20 deg,
sun ~35 deg from the east; 10 % albedo texture, 1 % noise) with its class map and texture mirrored
about the swath's centre column as in scene A' (the geometry is not), so the truth's own
east/west difference is 0 for every class and what is left after the correction is the
correction's error, not a brightness difference between the sides that an image-based fit may
take for BRDF (that confounding is issue 37's). Its man-made classes have a backscatter part and a
specular lobe (``ross_li_ts``), all from published values:

* roof tile: the Roy et al. (2016) red-band kernel weights plus the roof-tile lobe of paper 003,
  Table 1 (t1, w, n, k);
* concrete: the Roy et al. NIR weights plus the red-concrete lobe of Table 1;
* grass and soil: bench_kernels' RTLSR vegetation and soil (one lobe, backscatter only).

The intensities (kernel weights and t1) are scaled per band by bench_kernels' illustrative
spectra, so every class has one shape and a spectrum. The correction takes every pixel to the
scene's mean sun zenith, nadir view.

Metrics (bench_kernels' module docstring): the median relative error against the truth carrying
the same noise, and per class the east/west difference after the correction, worst band (the
truth's own is 0). Goals: median <= 0.5 %, worst class east/west <= 0.3 %.

    python benchmarks/bench_two_lobe_scene.py [--small]
"""

from __future__ import annotations

import time

import numpy as np
from bench_kernels import (
    CONCRETE,
    GRASS,
    ROOF,
    RTLSR,
    SOIL,
    URBAN_NAMES,
    class_map,
    correct,
    endmember_spectra,
    fit,
    gradient_table,
    line_geometry,
    mirrored,
    render_classes,
    rtlsr_weights,
    scene_parser,
    scores,
    smooth_field,
    urban_classes,
    verdict,
)

from brdfcorr.fit import ClassModels
from brdfcorr.models import get_model, load_material
from brdfcorr.models.coefficients import load_coefficients

TWO_LOBE = get_model("ross_li_ts")
MAN_MADE = (ROOF, CONCRETE)
#: The fits compared: a name -> the model of the man-made classes (grass and soil keep RTLSR).
FITS = {
    "auto (held-out choice)": "auto",
    "two-lobe (ross_li_ts)": "ross_li_ts",
    "Torrance-Sparrow only": "torrance_sparrow",
    "kernels only (RTLSR)": "ross_thick_li_sparse",
}


def two_lobe_params(kernel_band: str, material: str, spectrum: np.ndarray) -> dict[str, np.ndarray]:
    """Per band: Roy et al. (2016) kernel weights of ``kernel_band`` and the paper-003 lobe of
    ``material``, their intensities (f_iso, f_vol, f_geo, t1) times ``spectrum`` (relative)."""
    kernels = load_coefficients("roy2016").params(kernel_band)
    lobe = load_material(material).params
    params = {name: float(value) * spectrum for name, value in kernels.items()}
    params["t1"] = float(lobe["t1"]) * spectrum
    params.update({name: np.full(spectrum.shape, float(lobe[name])) for name in ("w", "n", "k")})
    return params


def scene_two_lobe(rows: int, columns: int, bands: int, noise: float, seed: int = 1) -> dict:
    """Scene B, mirrored, with two-lobe roof tile and concrete (module docstring)."""
    rng = np.random.default_rng(seed)
    wavelengths = np.linspace(400.0, 1000.0, bands)
    angles = line_geometry(rows, columns)
    classes = mirrored(urban_classes(rows, columns, rng))
    texture = mirrored(1.0 + 0.1 * smooth_field(rng, (rows, columns), 2.0))
    soil = endmember_spectra(wavelengths)["soil"]
    brick = soil / np.interp(650.0, wavelengths, soil)  # reddish: rises through the visible
    grey = 0.9 + 0.2 * (wavelengths - 400.0) / 600.0
    weights = rtlsr_weights(wavelengths)
    models = {ROOF: (TWO_LOBE, two_lobe_params("red", "roof_tile", brick)),
              CONCRETE: (TWO_LOBE, two_lobe_params("nir", "red_concrete", grey)),
              GRASS: (RTLSR, weights["vegetation"]), SOIL: (RTLSR, weights["soil"])}
    return render_classes(models, classes, texture, angles, wavelengths, rng, noise)


def main() -> None:
    parser = scene_parser(__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="120 x 180 x 20: a quick check")
    args = parser.parse_args()
    if args.small:
        args.rows, args.columns, args.bands = 120, 180, 20
    scene = scene_two_lobe(args.rows, args.columns, args.bands, args.noise)
    classes = class_map(scene, scene["classes"])
    print(f"two-lobe urban line, {args.bands} bands x {args.rows} x {args.columns}, noise {args.noise:.1%}")
    for label, model in FITS.items():
        start = time.perf_counter()
        result = fit(scene, classes, ClassModels("ross_thick_li_sparse", names=URBAN_NAMES,
                                                 class_models=dict.fromkeys(MAN_MADE, model)))
        fitted = time.perf_counter() - start
        corrected = correct(scene, classes, result.table)
        print(f"\n{label}: fit {fitted:.1f} s")
        for entry in result.fits:
            print(f"  fit {entry.name}: {entry.model}, {entry.status}, median R^2 {entry.median_r2:.3f}")
        gradient_table(scene, corrected, scene["classes"], URBAN_NAMES)
        values = scores(scene, corrected, scene["classes"], URBAN_NAMES)
        print(f"  median |error| {values['brdf']:.3%}{verdict(values['brdf'], 0.005)} (uncorrected "
              f"{values['raw']:.2%}); worst class east/west {values['after']:.2%}{verdict(values['after'], 0.003)} "
              f"(the truth's own {values['truth']:.2%})")


if __name__ == "__main__":
    main()
