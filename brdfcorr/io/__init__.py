"""Reading and writing: rasters through rioxarray/rasterio (:mod:`brdfcorr.io.rasters`), GeoTIFF
output (:mod:`brdfcorr.io.writer`), atomic output files and safe YAML (:mod:`brdfcorr.io.files`),
and sun/view angles as sensor products deliver them (:mod:`brdfcorr.io.sensors`).

The raster functions are imported on first use (``brdfcorr.io.open_image``): rasterio and
rioxarray take a while to load, and parameter tables and configs need only :mod:`.files`.
"""

import importlib

__all__ = ["open_angles", "open_classes", "open_image", "open_scene", "write_rasters"]

#: Lossless GeoTIFF compressions for reflectance (GDAL names, lower case; the CLI's choices).
COMPRESSIONS = ("deflate", "lzw", "zstd", "none")
#: Output raster formats (GDAL driver names; the CLI's ``--format`` choices).
FORMATS = ("GTiff", "ENVI")
#: File name extensions of each format (lower case; "" is a name without extension).
EXTENSIONS = {"GTiff": (".tif", ".tiff"), "ENVI": (".img", ".bsq", ".bil", ".dat", "")}


def __getattr__(name: str):
    if name in __all__:
        module = {"write_rasters": "brdfcorr.io.writer", "open_scene": "brdfcorr.io.scene"}.get(
            name, "brdfcorr.io.rasters")
        return getattr(importlib.import_module(module), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
