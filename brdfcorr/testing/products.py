"""Sensor products in their real layouts, written from synthetic values for tests, benchmarks and
the docs' worked examples: a Sentinel-2 L2A SAFE folder (``MTD_TL.xml`` angle grids), a Landsat
Collection-2 L2 folder, AVIRIS-NG ENVI lines with their ``obs_ort`` files, NEON AOP reflectance
HDF5 and EMIT L2A/L1B NetCDF granules with their GLT. Re-exported by :mod:`brdfcorr.testing`."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Literal

import numpy as np
import xarray as xr

from brdfcorr.io.sensors.envi import acquisition_time
from brdfcorr.io.writer import wavelength_text

__all__ = [
    "write_mtd_tl",
    "write_sentinel2_safe",
    "write_stac_item",
    "write_landsat_c2",
    "observation_layers",
    "write_envi_line",
    "write_neon_reflectance",
    "swath_glt",
    "write_emit_granules",
]

#: SCL classes written by :func:`write_sentinel2_safe` (a vegetation scene with some cloud).
SCL_VEGETATION, SCL_CLOUD_HIGH = 4, 9

def _values_list(grid: np.ndarray) -> str:
    rows = "".join(f"<VALUES>{' '.join(f'{v:.4f}' for v in row)}</VALUES>" for row in grid)
    return f"<COL_STEP unit=\"m\">5000</COL_STEP><ROW_STEP unit=\"m\">5000</ROW_STEP><Values_List>{rows}</Values_List>"


def write_mtd_tl(path: str | os.PathLike, *, crs: str = "EPSG:32632",
                 corner: tuple[float, float] = (300000.0, 5000040.0),
                 sun_zenith: tuple[float, float] = (35.0, 37.0), sun_azimuth: float = 150.0,
                 sensing_time: str = "2023-06-15T10:30:00.000Z",
                 view: tuple[np.ndarray, np.ndarray] | None = None) -> Path:
    """A synthetic Sentinel-2 L2A granule metadata file (``MTD_TL.xml``) with the elements
    :func:`brdfcorr.io.sensors.parse_mtd_tl` and sen2nbar read: a 109.8 km tile at ``corner``, a
    23 x 23 sun grid at 5 km (zenith rising north to south over ``sun_zenith``, one azimuth), and
    one detector per band whose view zenith grows from 0.5 deg at the tile's centre column to
    about 10 deg at its edges, seen towards the east-south-east (105 deg) west of the ground track
    and the west-north-west (285 deg) east of it (a sun-synchronous descending orbit), sensed at
    ``sensing_time`` (ISO 8601); ``view``: that detector's (zenith, azimuth) node grids (23 x 23)
    [deg] instead."""
    columns = np.arange(23) * 5000.0 - 54900.0  # node x relative to the tile's centre [m]
    sun_z = np.repeat(np.linspace(*sun_zenith, 23)[:, None], 23, axis=1)
    view_z = np.repeat((0.5 + 9.5 * np.abs(columns) / 55000.0)[None, :], 23, axis=0)
    view_a = np.repeat(np.where(columns < 0, 105.0, 285.0)[None, :], 23, axis=0)
    if view is not None:
        view_z, view_a = view
    sizes = "".join(f'<Size resolution="{r}"><NROWS>{109800 // r}</NROWS><NCOLS>{109800 // r}</NCOLS></Size>'
                    for r in (10, 20, 60))
    positions = "".join(f'<Geoposition resolution="{r}"><ULX>{corner[0]:g}</ULX><ULY>{corner[1]:g}</ULY>'
                        f"<XDIM>{r}</XDIM><YDIM>-{r}</YDIM></Geoposition>" for r in (10, 20, 60))
    views = "".join(f'<Viewing_Incidence_Angles_Grids bandId="{band}" detectorId="1"><Zenith>{_values_list(view_z)}'
                    f"</Zenith><Azimuth>{_values_list(view_a)}</Azimuth></Viewing_Incidence_Angles_Grids>"
                    for band in range(13))
    path = Path(path)
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<n1:Level-2A_Tile_ID xmlns:n1="https://psd-14.sentinel2.eo.esa.int'
        '/PSD/S2_PDI_Level-2A_Tile_Metadata.xsd"><n1:General_Info><SENSING_TIME>'
        f"{sensing_time}</SENSING_TIME></n1:General_Info><n1:Geometric_Info><Tile_Geocoding><HORIZONTAL_CS_CODE>{crs}"
        f"</HORIZONTAL_CS_CODE>{sizes}{positions}</Tile_Geocoding><Tile_Angles><Sun_Angles_Grid><Zenith>"
        f"{_values_list(sun_z)}</Zenith><Azimuth>{_values_list(np.full((23, 23), sun_azimuth))}</Azimuth>"
        f"</Sun_Angles_Grid>{views}</Tile_Angles></n1:Geometric_Info></n1:Level-2A_Tile_ID>\n")
    return path


def write_sentinel2_safe(directory: str | os.PathLike, mtd_tl: str | os.PathLike | None = None, *, size: int = 16,
                         offset: tuple[float, float] = (40000.0, 40000.0), baseline: str = "04.00",
                         seed: int = 0, sensed: tuple[str, tuple[float, float]] | None = None) -> Path:
    """A small Sentinel-2 L2A SAFE folder: a real granule's ``MTD_TL.xml`` (copied, its root
    retagged Level-2A as an L2A granule's is; None: :func:`write_mtd_tl`'s; with ``sensed``, a
    (time ``YYYYMMDDTHHMMSS``, sun zenith range [deg]) pair, :func:`write_mtd_tl`'s at that time and
    sun, the folder and file names dated alike: one date of a series), a product ``MTD_MSIL2A.xml`` (``baseline``,
    quantification 10000, BOA_ADD_OFFSET -1000 from 04.00), and synthetic bands written as GeoTIFFs
    under the L2A names (``R10m/..._B02_10m.jp2``; GDAL opens them by content): ``size`` x ``size``
    pixels at 20 m (2 ``size`` at 10 m) whose upper-left corner is ``offset`` [m] right of and below
    the tile's. DNs are uniform in 1500-5000 (reflectance 0.05-0.4 after the offset); the SCL is
    vegetation (4) except the first row at 20 m, cloud (9).
    """
    import rasterio
    from affine import Affine

    from brdfcorr.io.sensors.sentinel2 import parse_mtd_tl

    if sensed is not None and mtd_tl is not None:
        raise ValueError("write_sentinel2_safe: give mtd_tl or sensed, not both")
    name = "T23LLF"  # the tile of the real metadata in tests/data (file names only)
    when = "20190425T132241" if sensed is None else sensed[0]
    safe = Path(directory) / f"S2A_MSIL2A_{when}_N{baseline.replace('.', '')}_R038_{name}_{when[:8]}T164208.SAFE"
    granule = safe / "GRANULE" / f"L2A_{name}_A020055_{when[:8]}T132236"
    granule.mkdir(parents=True)
    if sensed is not None:
        stamp = f"{when[:4]}-{when[4:6]}-{when[6:8]}T{when[9:11]}:{when[11:13]}:{when[13:15]}.000Z"
        write_mtd_tl(granule / "MTD_TL.xml", sun_zenith=sensed[1], sensing_time=stamp)
    elif mtd_tl is None:
        write_mtd_tl(granule / "MTD_TL.xml")
    else:
        (granule / "MTD_TL.xml").write_text(Path(mtd_tl).read_text().replace("Level-1C_Tile_ID", "Level-2A_Tile_ID"))
    tile = parse_mtd_tl(granule / "MTD_TL.xml")
    offsets = "".join(f'<BOA_ADD_OFFSET band_id="{i}">-1000</BOA_ADD_OFFSET>' for i in range(13))
    (safe / "MTD_MSIL2A.xml").write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<n1:Level-2A_User_Product xmlns:n1="https://psd-14.sentinel2.eo.esa.int'
        '/PSD/User_Product_Level-2A.xsd"><n1:General_Info><Product_Info><PROCESSING_BASELINE>'
        f'{baseline}</PROCESSING_BASELINE></Product_Info><Product_Image_Characteristics>'
        '<QUANTIFICATION_VALUES_LIST><BOA_QUANTIFICATION_VALUE unit="none">10000</BOA_QUANTIFICATION_VALUE>'
        '</QUANTIFICATION_VALUES_LIST>'
        + (f"<BOA_ADD_OFFSET_VALUES_LIST>{offsets}</BOA_ADD_OFFSET_VALUES_LIST>" if float(baseline) >= 4 else "")
        + "</Product_Image_Characteristics></n1:General_Info></n1:Level-2A_User_Product>\n")
    rng = np.random.default_rng(seed)
    corner = tile.geopositions[10]
    layout = {10: ("B02", "B03", "B04", "B08"),
              20: ("B02", "B03", "B04", "B05", "B06", "B07", "B8A", "B11", "B12", "SCL")}
    for resolution, bands in layout.items():
        folder = granule / "IMG_DATA" / f"R{resolution}m"
        folder.mkdir(parents=True)
        n = size * 20 // resolution
        transform = Affine(resolution, 0.0, corner.c + offset[0], 0.0, -resolution, corner.f - offset[1])
        for band in bands:
            if band == "SCL":
                data = np.full((n, n), SCL_VEGETATION, dtype="uint8")
                data[0] = SCL_CLOUD_HIGH
            else:
                data = rng.integers(1500, 5000, size=(n, n), dtype="uint16")
            path = folder / f"{name}_{when}_{band}_{resolution}m.jp2"
            with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype=data.dtype,
                               crs=tile.crs, transform=transform, nodata=0) as dataset:
                dataset.write(data, 1)
    return safe


#: The band assets of Earth Search v1 ``sentinel-2-l2a`` items, copied from a real one
#: (``sentinel-s2-l2a-cogs/39/Q/TA/2023/6/S2A_39QTA_20230628_0_L2A``): per band, the asset key, which
#: is also its ``eo:bands`` name, the entry's ``common_name`` and ``center_wavelength`` [µm]. The
#: Planetary Computer keys and names the assets by band (``B04``) instead.
_EARTH_SEARCH_V1 = {"B02": ("blue", "blue", 0.49), "B03": ("green", "green", 0.56), "B04": ("red", "red", 0.665),
                    "B05": ("rededge1", "rededge", 0.704), "B06": ("rededge2", "rededge", 0.74),
                    "B07": ("rededge3", "rededge", 0.783), "B08": ("nir", "nir", 0.842),
                    "B8A": ("nir08", "nir08", 0.865), "B11": ("swir16", "swir16", 1.61),
                    "B12": ("swir22", "swir22", 2.19)}


def _stac_band_asset(band: str, href: str, layout: str, scaling: bool) -> tuple[str, dict]:
    """(key, asset) of one band file in ``layout`` (:func:`write_stac_item`)."""
    key, common, microns = _EARTH_SEARCH_V1[band]
    name = key if layout == "earth_search" else band
    asset = {"href": href, "type": "image/tiff; application=geotiff", "roles": ["data", "reflectance"],
             "eo:bands": [{"name": name, "common_name": common, "center_wavelength": microns}]}
    if scaling:
        asset["raster:bands"] = [{"nodata": 0, "data_type": "uint16", "scale": 0.0001, "offset": -0.1}]
    return name, asset


def write_stac_item(safe: str | os.PathLike, *, scaling: bool = True,
                    layout: Literal["earth_search", "planetary_computer"] = "earth_search") -> Path:
    """A STAC item (JSON, beside ``safe``) of a SAFE folder written by :func:`write_sentinel2_safe`.

    ``layout="earth_search"``: as Earth Search v1 publishes ``sentinel-2-l2a`` items
    (:data:`_EARTH_SEARCH_V1`): one asset per band keyed by its common name (``red``, ``nir08``),
    its ``eo:bands`` entry named so too, ``scl`` and ``granule_metadata``, and beside each band its
    JPEG 2000 copy (``red-jp2``, the same ``eo:bands`` entry) at a remote ``s3://`` href, as in the
    real items. ``layout="planetary_computer"``: keys and ``eo:bands`` names the band names
    (``B04``), ``SCL`` and ``granule-metadata``. With ``scaling``, each band's ``raster:bands`` scale
    0.0001 and offset -0.1. Local hrefs are relative to the item. The bands are the SAFE's 20 m
    files (B08 its 10 m file), so the item reads the same pixels as the folder at 20 m.
    """
    import json

    from brdfcorr.io.sensors.sentinel2 import parse_mtd_tl

    safe = Path(safe)
    granule = next(safe.glob("GRANULE/*"))
    tile = parse_mtd_tl(granule / "MTD_TL.xml")
    assets, copies = {}, {}
    for band in _EARTH_SEARCH_V1:
        resolution = 10 if band == "B08" else 20
        file = next((granule / "IMG_DATA" / f"R{resolution}m").glob(f"*_{band}_{resolution}m.jp2"))
        key, asset = _stac_band_asset(band, str(file.relative_to(safe.parent)), layout, scaling)
        assets[key] = asset
        if layout == "earth_search":  # the real items' remote JPEG 2000 copy, of the same eo:bands name
            copies[f"{key}-jp2"] = {**asset, "href": f"s3://sentinel-s2-l2a/tiles/{band}.jp2", "type": "image/jp2"}
    scl = next((granule / "IMG_DATA" / "R20m").glob("*_SCL_20m.jp2"))
    assets["scl" if layout == "earth_search" else "SCL"] = {
        "href": str(scl.relative_to(safe.parent)), "type": "image/tiff; application=geotiff", "roles": ["data"]}
    assets["granule_metadata" if layout == "earth_search" else "granule-metadata"] = {
        "href": str((granule / "MTD_TL.xml").relative_to(safe.parent)), "type": "application/xml",
        "roles": ["metadata"]}
    item = {"type": "Feature", "stac_version": "1.0.0", "id": safe.stem, "geometry": None,
            "properties": {"datetime": tile.sensing_time.isoformat(), "platform": "sentinel-2a",
                           "constellation": "sentinel-2", "s2:processing_baseline": "04.00"},
            "links": [], "assets": {**assets, **copies}}
    path = safe.parent / f"{safe.stem}.json"
    path.write_text(json.dumps(item, indent=1))
    return path


#: QA_PIXEL values written by :func:`write_landsat_c2`: clear land (bit 6) and cloud (bits 3, 6 off).
QA_CLEAR, QA_CLOUD = 1 << 6, (1 << 3) | (1 << 1)


def write_landsat_c2(directory: str | os.PathLike, ang: str | os.PathLike | None = None,
                     sza: str | os.PathLike | None = None, *, size: int = 16,
                     corner: tuple[float, float] = (550000.0, -2870000.0), seed: int = 0,
                     angle_bands: bool = False) -> Path:
    """A small Landsat 7 Collection-2 Level-2 folder: synthetic ``SR_B1`` ... ``SR_B7`` (uint16,
    DNs uniform in 9000-22000: reflectance 0.05-0.4 after scale 2.75e-5 and offset -0.2) and
    ``QA_PIXEL`` (clear, the first row cloud) of ``size`` x ``size`` 30 m pixels in UTM 21S
    (EPSG:32621, north as negative numbers as in the real ANG.txt) whose upper-left corner is
    ``corner``, with a real product's ``ANG.txt`` (and ``SZA`` band) copied in where given; with
    ``angle_bands`` four synthetic angle bands (``_SZA`` ... ``_VAA``, int16 hundredths of a degree
    as USGS stores them): sun zenith 40-42 deg north to south, sun azimuth 60 deg, view zenith 0 at
    the middle column, +0.5 deg per 16 columns, seen towards 100 deg west of it, -80 deg east."""
    import shutil

    import rasterio
    from affine import Affine

    folder = Path(directory) / "LE07_L2SP_225078_20110306_20200910_02_T1"
    folder.mkdir(parents=True)
    prefix = folder / folder.name
    if ang is not None:
        shutil.copy(ang, f"{prefix}_ANG.txt")
    if sza is not None:
        shutil.copy(sza, f"{prefix}_SZA.TIF")
    rng = np.random.default_rng(seed)
    profile = {"driver": "GTiff", "width": size, "height": size, "count": 1, "dtype": "uint16",
               "crs": "EPSG:32621", "transform": Affine(30.0, 0.0, corner[0], 0.0, -30.0, corner[1])}
    for band in (1, 2, 3, 4, 5, 7):
        with rasterio.open(f"{prefix}_SR_B{band}.TIF", "w", nodata=0, **profile) as dataset:
            dataset.write(rng.integers(9000, 22000, size=(size, size), dtype="uint16"), 1)
    qa = np.full((size, size), QA_CLEAR, dtype="uint16")
    qa[0] = QA_CLOUD
    with rasterio.open(f"{prefix}_QA_PIXEL.TIF", "w", nodata=1, **profile) as dataset:
        dataset.write(qa, 1)
    if angle_bands:
        columns = np.arange(size) - (size - 1) / 2.0
        angles = {"SZA": np.repeat(np.linspace(40.0, 42.0, size)[:, None], size, axis=1),
                  "SAA": np.full((size, size), 60.0),
                  "VZA": np.repeat((np.abs(columns) * 0.5 / 16.0)[None, :], size, axis=0),
                  "VAA": np.repeat(np.where(columns < 0, 100.0, -80.0)[None, :], size, axis=0)}
        for name, values in angles.items():
            with rasterio.open(f"{prefix}_{name}.TIF", "w", **{**profile, "dtype": "int16"}) as dataset:
                dataset.write(np.round(values * 100.0).astype("int16"), 1)
    return folder


# --- Imaging-spectrometer products (AVIRIS-NG ENVI, NEON AOP HDF5, EMIT NetCDF) of a scene ----------
# The writers below take a scene as :func:`brdfcorr.chain.demo.demo_scene` returns it (an
# xarray.Dataset with ``reflectance`` (band, y, x) and its ``wavelength`` coordinate [nm], the four
# angles sza, saa, vza, vaa [deg] on (y, x), north-up, with CRS and transform) and write it in a
# product's own layout, as its reader in :mod:`brdfcorr.io.sensors` documents it.

#: Fill value of the three products (AVIRIS-NG ``data ignore value``, NEON ``Data_Ignore_Value``,
#: EMIT ``_FillValue``).
PRODUCT_FILL = -9999.0

#: Band names of a JPL observation file (AVIRIS-NG/-3 ``obs``/``obs_ort`` header, as in the real
#: line ang20160910t185702), in their order.
OBS_BAND_NAMES = (
    "Path length (m)",
    "To-sensor azimuth (0 to 360 degrees cw from N)",
    "To-sensor zenith (0 to 90 degrees from zenith)",
    "To-sun azimuth (0 to 360 degrees cw from N)",
    "To-sun zenith (0 to 90 degrees from zenith)",
    "Solar phase",
    "Slope",
    "Aspect",
    "Cosine(i)",
    "UTC Time",
    "Earth-sun distance (AU)",
)


def _unit_vectors(azimuth, zenith) -> np.ndarray:
    """(east, north, up) unit vectors of directions at ``azimuth`` (cw from north) and ``zenith`` [deg]."""
    azimuth, zenith = np.radians(azimuth), np.radians(zenith)
    return np.stack([np.sin(zenith) * np.sin(azimuth), np.sin(zenith) * np.cos(azimuth), np.cos(zenith)])


def observation_layers(scene: xr.Dataset, altitude: float, utc_hours: float) -> np.ndarray:
    """The 11 layers (band, y, x) of a JPL observation file (:data:`OBS_BAND_NAMES`) of a flat scene.

    Path length = ``altitude`` [m] / cos(vza); solar phase = the angle between the to-sun and
    to-sensor unit vectors [deg] (what the real files hold, see :mod:`brdfcorr.io.sensors.envi`);
    slope 0 and aspect 0 (flat ground), so cos(i) = cos(sza); UTC time ``utc_hours`` [h]; Earth-sun
    distance 1.0 AU. NaN angles give NaN in every layer.
    """
    sza, saa, vza, vaa = (scene[name].values.astype(np.float64) for name in ("sza", "saa", "vza", "vaa"))
    cos_phase = np.sum(_unit_vectors(saa, sza) * _unit_vectors(vaa, vza), axis=0)
    phase = np.degrees(np.arccos(np.clip(cos_phase, -1.0, 1.0)))  # clip: rounding may leave |cos| > 1
    valid = np.isfinite(sza + saa + vza + vaa)
    flat = np.where(valid, 0.0, np.nan)
    return np.stack([altitude / np.cos(np.radians(vza)), vaa, vza, saa, sza, phase, flat, flat,
                     np.cos(np.radians(sza)), flat + utc_hours, flat + 1.0])


def _stored(values: np.ndarray) -> np.ndarray:
    """NaN as :data:`PRODUCT_FILL`."""
    return np.where(np.isfinite(values), values, PRODUCT_FILL)


def _write_envi(path: Path, data: np.ndarray, scene: xr.Dataset, dtype: str, interleave: str,
                descriptions, header: dict[str, str]) -> Path:
    """One ENVI file (band, y, x) on the scene's grid through GDAL's ENVI driver, with band names
    ``descriptions`` and extra header fields ``header`` (items of the ENVI metadata domain)."""
    import rasterio

    profile = {"driver": "ENVI", "width": data.shape[2], "height": data.shape[1], "count": data.shape[0],
               "dtype": dtype, "crs": scene.rio.crs, "transform": scene.rio.transform(),
               "nodata": PRODUCT_FILL, "interleave": interleave.upper()}
    with rasterio.Env(GDAL_PAM_ENABLED="NO"):  # no .aux.xml sidecar: the header holds everything
        with rasterio.open(path, "w", **profile) as dataset:
            dataset.write(_stored(data).astype(dtype))
            dataset.descriptions = tuple(descriptions)
        if header:
            with rasterio.open(path, "r+") as dataset:
                dataset.update_tags(ns="ENVI", **header)
    return path


def write_envi_line(directory: str | os.PathLike, scene: xr.Dataset, name: str = "ang20260615t080000", *,
                    altitude: float = 1000.0, fwhm: float = 5.5) -> dict[str, Path]:
    """An AVIRIS-NG-like orthorectified line in ENVI format: ``{name}_rfl`` (reflectance factors,
    float32, BIL, ``wavelength``/``fwhm`` [nm] and ``data ignore value`` -9999 in the header, as the
    L2 reflectance) and ``{name}_obs_ort`` (the 11 float64 BSQ layers of
    :func:`observation_layers`, named as in the real obs files), both with map info and CRS.

    ``name`` starts with the line's UTC time (``angYYYYMMDDtHHMMSS``, the time of the scene's
    sun, written to the UTC time layer); ``altitude`` [m] gives the path lengths, ``fwhm`` [nm]
    the bands' width.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    wavelength = scene["wavelength"].values
    spectral = {"wavelength": "{" + ", ".join(map(wavelength_text, wavelength)) + "}",
                "fwhm": "{" + ", ".join(wavelength_text(fwhm) for _ in wavelength) + "}",
                "wavelength_units": "Nanometers"}
    time = acquisition_time(name)
    hours = time.hour + time.minute / 60 + time.second / 3600
    image = _write_envi(directory / f"{name}_rfl", scene["reflectance"].values, scene, "float32", "bil",
                        [f"{value:g} Nanometers" for value in wavelength], spectral)
    obs = _write_envi(directory / f"{name}_obs_ort", observation_layers(scene, altitude, hours), scene,
                      "float64", "bsq", OBS_BAND_NAMES, {})
    return {"image": image, "obs": obs}


def _map_info(scene: xr.Dataset) -> str:
    """ENVI map info of the scene's north-up UTM grid (reference pixel (1, 1) at the upper-left corner)."""
    crs, transform = scene.rio.crs, scene.rio.transform()
    zone = crs.to_dict().get("zone") if crs.to_dict().get("proj") == "utm" else None
    if zone is None or transform.b or transform.d:
        raise ValueError(f"a NEON Map_Info needs a north-up UTM grid, got {crs} {tuple(transform)[:6]}")
    hemisphere = "South" if crs.to_dict().get("south") else "North"
    return (f"UTM,  1.000,  1.000,  {transform.c:.2f},  {transform.f:.2f},  {transform.a:.10e},  {-transform.e:.10e},"
            f"  {zone},  {hemisphere},  WGS-84,  units=Meters, rotation=0.000")


def write_neon_reflectance(directory: str | os.PathLike, scene: xr.Dataset, *, site: str = "DEMO",
                           domain: str = "D00", flight_line: str = "080000", date: str = "20260615",
                           fwhm: float = 5.0) -> Path:
    """A NEON AOP directional reflectance flight line (DP1.30006.001 HDF5 layout) of ``scene``:
    ``/<site>/Reflectance/Reflectance_Data`` (rows, columns, bands) int16 = reflectance x 10000
    (``Scale_Factor`` 10000, ``Data_Ignore_Value`` -9999), ``Metadata/Spectral_Data`` wavelengths
    and FWHM [nm], ``Coordinate_System/Map_Info`` and ``EPSG Code``, the view rasters
    ``to-sensor_Zenith_Angle``/``to-sensor_Azimuth_Angle`` [deg] and the flight line's sun
    (``Logs/<flight_line>``: one zenith and azimuth, the scene's means [deg], as NEON logs them).

    Named ``NEON_<domain>_<site>_DP1_<date>_<flight_line>_reflectance.h5``; the default site code
    ``DEMO`` is no NEON site (the scene is synthetic).
    """
    import h5py

    path = Path(directory) / f"NEON_{domain}_{site}_DP1_{date}_{flight_line}_reflectance.h5"
    path.parent.mkdir(parents=True, exist_ok=True)
    cube = np.moveaxis(scene["reflectance"].values, 0, -1)
    stored = np.where(np.isfinite(cube), np.round(cube * 10000.0), PRODUCT_FILL)
    if np.any(np.abs(stored) > np.iinfo("int16").max):  # int16 would wrap around silently
        raise ValueError("reflectance beyond +-3.2767 cannot be stored as NEON's int16 x 10000")
    stored = stored.astype("int16")
    with h5py.File(path, "w") as h5file:
        group = h5file.create_group(f"{site}/Reflectance")
        data = group.create_dataset("Reflectance_Data", data=stored, chunks=(min(64, stored.shape[0]),
                                    min(64, stored.shape[1]), stored.shape[2]), compression="gzip")
        data.attrs.update({"Scale_Factor": 10000.0, "Data_Ignore_Value": PRODUCT_FILL,
                           "Description": "Atmospherically corrected reflectance.",
                           "Dimension_Labels": "Line, Sample, Wavelength", "Interleave": "BIP"})
        metadata = group.create_group("Metadata")
        wavelength = metadata.create_dataset("Spectral_Data/Wavelength", data=scene["wavelength"].values)
        wavelength.attrs["Units"] = "nanometers"
        metadata.create_dataset("Spectral_Data/FWHM", data=np.full(cube.shape[2], fwhm))
        metadata.create_dataset("Coordinate_System/Map_Info", data=_map_info(scene).encode())
        metadata.create_dataset("Coordinate_System/EPSG Code", data=str(scene.rio.crs.to_epsg()).encode())
        for item, key in (("to-sensor_Zenith_Angle", "vza"), ("to-sensor_Azimuth_Angle", "vaa")):
            layer = metadata.create_dataset(item, data=_stored(scene[key].values).astype("float32"))
            layer.attrs["Data_Ignore_Value"] = PRODUCT_FILL
        log = metadata.create_group(f"Logs/{flight_line}")
        log.create_dataset("Solar_Zenith_Angle", data=float(np.nanmean(scene["sza"].values)))
        log.create_dataset("Solar_Azimuth_Angle", data=float(np.nanmean(scene["saa"].values)))
    return path


#: Band names of an EMIT L1B OBS granule (``sensor_band_parameters/observation_bands``), in order.
EMIT_OBS_BAND_NAMES = (
    "Path length (sensor-to-ground in meters)",
    "To-sensor azimuth (0 to 360 degrees CW from N)",
    "To-sensor zenith (0 to 90 degrees from zenith)",
    "To-sun azimuth (0 to 360 degrees CW from N)",
    "To-sun zenith (0 to 90 degrees from zenith)",
    "Solar phase (degrees between to-sensor and to-sun vectors in principal plane)",
    "Slope (local surface slope as derived from DEM in degrees)",
    "Aspect (local surface aspect 0 to 360 degrees clockwise from N)",
    "Cosine(i) (apparent local illumination factor based on DEM slope and aspect and to sun vector)",
    "UTC Time (decimal hours for mid-line pixels)",
    "Earth-sun distance (AU)",
)

#: Metres per degree of latitude (spherical Earth, as the GLT helper below needs no more).
METRES_PER_DEGREE = 111_320.0


def swath_glt(shape: tuple[int, int], pixel: float, heading: float, latitude: float) -> dict:
    """A geometry lookup table (GLT) of a straight swath on a north-up lon/lat grid, EMIT's rule.

    The swath (``shape`` = downtrack, crosstrack pixels of ``pixel`` [m]) is flown towards
    ``heading`` [deg cw from north], downtrack index growing along the track and crosstrack index
    to its right, centred on the grid. The grid has square cells of ``pixel / 111320`` deg (as
    EMIT's, square in degrees) at ``latitude`` [deg]; cell (i, j) shows the swath pixel its centre
    falls in: ``glt_y`` = downtrack + 1, ``glt_x`` = crosstrack + 1, 0 outside the swath.

    Returns ``glt_x``, ``glt_y`` (ortho_y, ortho_x) int32, the swath pixel centres' ``east`` and
    ``north`` [m] from the swath centre (downtrack, crosstrack), and ``corner`` (east, north) [m] of
    the grid's upper-left corner.
    """
    down, cross = shape
    h = np.radians(heading)
    along = np.array([-1.0, -1.0, 1.0, 1.0]) * down * pixel / 2
    across = np.array([-1.0, 1.0, -1.0, 1.0]) * cross * pixel / 2
    east = across * np.cos(h) + along * np.sin(h)
    north = -across * np.sin(h) + along * np.cos(h)
    cell_x, cell_y = pixel * np.cos(np.radians(latitude)), pixel  # [m] of one square-degree cell
    columns = int(np.ceil((east.max() - east.min()) / cell_x))
    rows = int(np.ceil((north.max() - north.min()) / cell_y))
    cell_east = east.min() + (np.arange(columns) + 0.5) * cell_x
    cell_north = north.max() - (np.arange(rows) + 0.5) * cell_y
    e, n = np.meshgrid(cell_east, cell_north)
    row = np.floor((e * np.sin(h) + n * np.cos(h)) / pixel + down / 2).astype(int)
    col = np.floor((e * np.cos(h) - n * np.sin(h)) / pixel + cross / 2).astype(int)
    inside = (row >= 0) & (row < down) & (col >= 0) & (col < cross)
    r, c = np.meshgrid((np.arange(down) + 0.5 - down / 2) * pixel, (np.arange(cross) + 0.5 - cross / 2) * pixel,
                       indexing="ij")
    return {"glt_x": np.where(inside, col + 1, 0).astype("int32"),
            "glt_y": np.where(inside, row + 1, 0).astype("int32"),
            "east": c * np.cos(h) + r * np.sin(h), "north": -c * np.sin(h) + r * np.cos(h),
            "corner": (float(east.min()), float(north.max()))}


def _write_granule(path: Path, name: str, cube: np.ndarray, band_parameters: dict, location: dict,
                   attrs: dict) -> Path:
    """An EMIT NetCDF granule: root ``name`` (downtrack, crosstrack, bands) float32 with _FillValue
    -9999 and global ``attrs``, groups ``sensor_band_parameters`` and ``location``."""
    root = xr.Dataset({name: (("downtrack", "crosstrack", "bands"), _stored(cube).astype("float32"))}, attrs=attrs)
    root.to_netcdf(path, engine="h5netcdf", encoding={name: {"_FillValue": np.float32(PRODUCT_FILL)}})
    xr.Dataset({key: ("bands", values) for key, values in band_parameters.items()}).to_netcdf(
        path, mode="a", group="sensor_band_parameters", engine="h5netcdf")
    xr.Dataset({key: (("ortho_y", "ortho_x") if key.startswith("glt") else ("downtrack", "crosstrack"), value)
                for key, value in location.items()}).to_netcdf(path, mode="a", group="location", engine="h5netcdf")
    return path


def write_emit_granules(directory: str | os.PathLike, scene: xr.Dataset, *, heading: float = 0.0,
                        granule: str = "001_20260615T080000_2616607_001", altitude: float = 410e3,
                        fwhm: float = 8.5) -> dict[str, Path]:
    """EMIT L2A reflectance and L1B OBS granules (V001 NetCDF layout, :mod:`brdfcorr.io.sensors.emit`)
    of a north-up ``scene`` taken as a swath flown north (downtrack 0: its southern row).

    The swath is laid on a lon/lat grid by :func:`swath_glt` around the scene's centre, turned by
    ``heading`` [deg]; both azimuths turn with it (saa and vaa + ``heading``), so every pixel keeps
    its relative azimuth, and so the reflectance it was rendered with. ``altitude`` [m] gives the
    OBS path lengths. Returns the paths ``reflectance`` (``EMIT_L2A_RFL_<granule>.nc``) and ``obs``
    (``EMIT_L1B_OBS_<granule>.nc``).
    """
    import rasterio.warp

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    pixel = abs(scene.rio.transform().a)
    lon, lat = rasterio.warp.transform(scene.rio.crs, "EPSG:4326", [float(scene.x.mean())], [float(scene.y.mean())])
    glt = swath_glt((scene.sizes["y"], scene.sizes["x"]), pixel, heading, lat[0])
    turned = scene.isel(y=slice(None, None, -1))  # downtrack 0 = the first line of a northbound flight
    for key in ("saa", "vaa"):
        turned[key] = (turned[key] + heading) % 360.0
    scale_x = METRES_PER_DEGREE * np.cos(np.radians(lat[0]))
    location = {"glt_x": glt["glt_x"], "glt_y": glt["glt_y"], "lat": lat[0] + glt["north"] / METRES_PER_DEGREE,
                "lon": lon[0] + glt["east"] / scale_x}
    cell = pixel / METRES_PER_DEGREE
    attrs = {"geotransform": [lon[0] + glt["corner"][0] / scale_x, cell, 0.0,
                              lat[0] + glt["corner"][1] / METRES_PER_DEGREE, 0.0, -cell],
             "spatial_ref": rasterio.crs.CRS.from_epsg(4326).to_wkt()}
    wavelength = turned["wavelength"].values
    paths = {"reflectance": directory / f"EMIT_L2A_RFL_{granule}.nc", "obs": directory / f"EMIT_L1B_OBS_{granule}.nc"}
    _write_granule(paths["reflectance"], "reflectance", np.moveaxis(turned["reflectance"].values, 0, -1),
                   {"wavelengths": wavelength, "fwhm": np.full(wavelength.size, fwhm),
                    "good_wavelengths": np.ones(wavelength.size, "uint8")}, location,
                   {**attrs, "title": "EMIT L2A Estimated Surface Reflectance"})
    start = re.search(r"T(\d{2})(\d{2})(\d{2})", granule)
    hours = 0.0 if start is None else int(start[1]) + int(start[2]) / 60 + int(start[3]) / 3600
    obs = observation_layers(turned, altitude, hours)
    _write_granule(paths["obs"], "obs", np.moveaxis(obs, 0, -1),
                   {"observation_bands": np.array(EMIT_OBS_BAND_NAMES, dtype=object)}, location,
                   {**attrs, "title": "EMIT L1B At-Sensor Calibrated Radiance and Geolocation Data"})
    return paths
