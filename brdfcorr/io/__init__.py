"""Reading and writing: an image identified once, its chunk and cache sizes (:mod:`.product`),
images and class maps (:mod:`.rasters`), angle rasters (:mod:`.angles`),
band centres (:mod:`.wavelengths`), the grid check (:mod:`.grid`), a whole scene (:mod:`.scene`),
GeoTIFF and ENVI output (:mod:`.writer`), atomic output files and safe YAML (:mod:`.files`), the
output guard (:mod:`.paths`), and what sensor products deliver (:mod:`.sensors`).

The raster functions are imported on first use (``brdfcorr.io.open_image``): rasterio and
rioxarray take a while to load, and parameter tables and configs need only :mod:`.files`.
"""

from brdfcorr._lazy import attach

#: The public face of the package, imported on first use: name -> module.
_PUBLIC = {
    "open_image": "rasters", "open_classes": "rasters", "check_reflectance_scale": "scale_check",
    "auto_chunk": "product", "open_angles": "angles", "check_angles": "angles", "ANGLE_NAMES": "angles",
    "open_scene": "scene", "SceneSources": "scene", "check_same_grid": "grid", "open_layer": "opening",
    "band_wavelengths": "wavelengths", "parse_wavelength": "wavelengths", "write_rasters": "writer",
    "GeoTiffOutput": "writer",
}
__all__ = list(_PUBLIC)

#: Lossless GeoTIFF compressions for reflectance (GDAL names, lower case; the CLI's choices).
COMPRESSIONS = ("deflate", "lzw", "zstd", "none")
#: Output raster formats (GDAL driver names; the CLI's ``--format`` choices).
FORMATS = ("GTiff", "ENVI")
#: File name extensions of each format (lower case; "" is a name without extension).
EXTENSIONS = {"GTiff": (".tif", ".tiff"), "ENVI": (".img", ".bsq", ".bil", ".dat", "")}


__getattr__, __dir__ = attach(__name__, _PUBLIC)
