"""Write a synthetic goniometer measurement table of a paper-003 material, to try `brdfcorr fit`.

The geometry mimics the EGO measurements of Meister et al. (2000): principal-plane scans at lamp
zeniths 30, 50 and 65 deg and azimuthal scans at (30, 30), (50, 50), (65, 70) and (65, 50) deg; the
BRDF is the material's Torrance-Sparrow model of Table 1 with Gaussian relative noise (4 % by
default, the paper's lowest total error), and sigma is that error.

    python examples/make_goniometer_csv.py roof_tile roof_tile.csv
    brdfcorr fit roof_tile.csv --fix k=0.25 --min-phi 90 -o params.yaml --plot-dir plots

Materials: spectralon_50, roof_tile, red_concrete, blue_concrete, red_aluminium
(`brdfcorr materials` lists them).
"""

from __future__ import annotations

import argparse

from brdfcorr.fit.measurements import write_measurements
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models.materials import load_material


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("material", help="built-in material name, e.g. roof_tile")
    parser.add_argument("output", help="CSV file to write")
    parser.add_argument("--noise", type=float, default=0.04, help="relative 1-sigma noise [-]")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    args = parser.parse_args(argv)

    material = load_material(args.material)
    data = synthesize_measurements(
        material.model, material.params, *goniometer_angles(),
        relative_noise=args.noise, seed=args.seed, source=material.label,
    )
    write_measurements(args.output, data)
    print(f"wrote {len(data)} measurements of {material.label} to {args.output}")


if __name__ == "__main__":
    main()
