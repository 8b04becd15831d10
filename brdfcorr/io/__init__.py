"""Reading and writing: rasters through rioxarray/rasterio (:mod:`brdfcorr.io.rasters`), atomic
output files and safe YAML (:mod:`brdfcorr.io.files`), and sun/view angles as sensor products
deliver them (:mod:`brdfcorr.io.sensors`)."""

from brdfcorr.io.rasters import open_angles, open_classes, open_image, open_scene, write_rasters

__all__ = ["open_angles", "open_classes", "open_image", "open_scene", "write_rasters"]
