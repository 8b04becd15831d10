"""Write a stand-in land-cover map for the demo scene, to try `brdfcorr classes align`.

A land-cover product differs from a class map made for a flight line in three ways, and this map
has all three: its own codes (the ESA WorldCover legend: 10 tree cover, 30 grassland, 50 built-up,
60 bare / sparse vegetation; it cannot tell roof tiles from concrete), its own CRS (geographic,
EPSG:4326) and its own resolution (about 5 m). It is made from the demo's class map:

    python examples/make_landcover.py demo_output/scene/line01_classes.tif demo_output/landcover.tif
    brdfcorr classes align demo_output/landcover.tif --like demo_output/scene/line01_image.tif \\
        --lookup examples/worldcover_lookup.yaml -o demo_output/landcover_on_grid.tif
"""

from __future__ import annotations

import argparse

import numpy as np
import rioxarray
from rasterio.enums import Resampling

#: Demo class id -> ESA WorldCover code (roof tile and concrete are both "built-up").
WORLDCOVER_OF_DEMO = {1: 50, 2: 50, 3: 30, 4: 10, 5: 60}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("classes", help="the demo scene's class map")
    parser.add_argument("output", help="land-cover GeoTIFF to write")
    args = parser.parse_args(argv)

    classes = rioxarray.open_rasterio(args.classes).squeeze("band", drop=True)
    codes = np.zeros(int(classes.max()) + 1, dtype=np.uint8)
    for class_id, code in WORLDCOVER_OF_DEMO.items():
        if class_id < codes.size:
            codes[class_id] = code
    landcover = classes.copy(data=codes[classes.values]).rio.write_nodata(0)
    landcover = landcover.rio.reproject("EPSG:4326", resolution=5e-5, resampling=Resampling.nearest, nodata=0)
    landcover.rio.to_raster(args.output, compress="deflate")
    print(f"wrote {args.output} (WorldCover codes {sorted(set(WORLDCOVER_OF_DEMO.values()))}, EPSG:4326)")


if __name__ == "__main__":
    main()
