"""The Python API checks what the command line checks (issue 38): integer counts and their scale,
angles in radians, bands last, a class map on another grid, a reference in radians; and its
messages name Python arguments (``wavelengths=``), not command-line flags."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from brdfcorr._entry import entered
from brdfcorr.correction import QA, normalize
from brdfcorr.errors import BrdfcorrWarning, GridMismatchError, InputError, ParameterError
from brdfcorr.fit import Sampling
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=24, nx=32)


def _angles(scene) -> dict:
    return {name: scene[name] for name in ANGLES}


def test_integer_counts_without_a_scale_are_refused_in_python_words(scene):
    counts = (scene["reflectance"] * 10000).astype(np.uint16)
    with pytest.raises(InputError, match=r"integer counts \(uint16\) without a scale_factor") as caught:
        normalize(counts, scene["classes"], _angles(scene), example_table())
    assert "reflectance * scale + offset" in str(caught.value) and "--scale" not in str(caught.value)


def test_integer_counts_with_scale_and_offset_are_corrected_as_factors(scene):
    # Sentinel-2 L2A from baseline 04.00: reflectance = counts * 0.0001 - 0.1 (an offset left out
    # would shift every corrected value by 0.1 * (factor - 1)).
    factors = scene["reflectance"].clip(0, 5)
    counts = np.round((factors + 0.1) / 0.0001).astype(np.uint16)
    counts.attrs.update(scale_factor=0.0001, add_offset=-0.1)
    stored = xr.DataArray(counts.values * 0.0001 - 0.1, dims=counts.dims, coords=counts.coords)  # what they stand for
    expected = normalize(stored.astype(np.float32), scene["classes"], _angles(scene), example_table()).reflectance
    corrected = normalize(counts, scene["classes"], _angles(scene), example_table()).reflectance
    np.testing.assert_allclose(corrected.values, expected.values, rtol=1e-5, atol=1e-6)
    assert corrected.attrs["brdf_input_offset"] == -0.1


def test_angles_in_radians_are_refused_numpy_at_once_dask_when_computed(scene):
    radians = {name: np.radians(scene[name]) for name in ANGLES}
    with pytest.raises(InputError, match=r"angles: the angles look like radians \(sza 0\.5"):
        normalize(scene["reflectance"], scene["classes"], radians, example_table())
    chunked = {name: layer.chunk({"y": 12}) for name, layer in radians.items()}
    lazy = normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"], chunked, example_table())
    with pytest.raises(InputError, match="look like radians.*np.degrees converts them"):
        lazy.reflectance.compute()
    # The same layers in degrees pass, numpy and dask alike.
    normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"], _angles(scene), example_table()).qa.compute()


@pytest.mark.parametrize("as_numpy", [True, False])
def test_bands_last_is_refused_with_the_transpose_that_fixes_it(scene, as_numpy):
    cube = scene["reflectance"].transpose("y", "x", "band")
    if as_numpy:
        with pytest.raises(InputError, match=r"bands last, \(y, x, band\); transpose to \(band, y, x\): "
                                             r"np.moveaxis\(reflectance, -1, 0\)"):
            normalize(cube.values, scene["classes"].values, {n: scene[n].values for n in ANGLES}, example_table())
    else:
        with pytest.raises(InputError, match=r"transpose to \(band, y, x\): reflectance.transpose\('band', 'y', 'x'\)"):
            normalize(cube, scene["classes"], _angles(scene), example_table())


def test_messages_name_python_arguments_in_python_and_flags_in_the_cli(scene):
    bare = scene["reflectance"].drop_vars("wavelength")  # the table's class 2 is per wavelength
    with pytest.raises(ParameterError, match="wavelengths=") as caught:
        normalize(bare, scene["classes"], _angles(scene), example_table())
    assert "--wavelengths" not in str(caught.value)
    with entered("cli"), pytest.raises(ParameterError, match="--wavelengths"):
        normalize(bare, scene["classes"], _angles(scene), example_table())
    with entered("chain"), pytest.raises(ParameterError, match="inputs.wavelengths"):
        normalize(bare, scene["classes"], _angles(scene), example_table())


def test_a_class_map_on_another_grid_names_align_class_map(scene):
    other = scene["classes"].rio.write_crs("EPSG:32633")
    with pytest.raises(GridMismatchError, match=r"brdfcorr.strata.align_class_map\(classes, reflectance\)"):
        normalize(scene["reflectance"], other, _angles(scene), example_table())


def test_a_reference_sun_zenith_in_radians_is_refused(scene):
    with pytest.raises(ParameterError, match=r"reference sza = 0.78 looks like radians \(44.69 deg\)"):
        normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table(), reference={"sza": 0.78})
    normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table(), reference={"sza": 0})


def test_a_coefficient_set_by_name_and_no_class_map_correct_every_pixel(scene):
    from brdfcorr.models.coefficients import load_coefficients
    from brdfcorr.params import ClassEntry

    table = ParameterTable(classes=[ClassEntry(**load_coefficients("roy2017").table_entry(1))])
    ones = xr.ones_like(scene["classes"])
    expected = normalize(scene["reflectance"], ones, _angles(scene), table, reference={"sza": 45})
    corrected = normalize(scene["reflectance"], None, _angles(scene), "roy2017", reference={"sza": 45})
    np.testing.assert_array_equal(corrected.reflectance.values, expected.reflectance.values)
    assert not np.any(corrected.reflectance.values == scene["reflectance"].values)  # every pixel corrected
    with pytest.raises(Exception, match="roy2071"):
        normalize(scene["reflectance"], None, _angles(scene), "roy2071")


def test_layers_with_dims_x_y_are_taken_by_name_not_by_position(scene):
    # A square image without coordinates: the layers' (x, y) would fit the grid read as (y, x).
    square = synthetic_scene(ny=24, nx=24)
    angles = _angles(square)
    expected = normalize(square["reflectance"], square["classes"], angles, example_table()).reflectance
    swapped = {name: xr.DataArray(layer.values.T, dims=("x", "y")) for name, layer in angles.items()}
    classes = xr.DataArray(square["classes"].values.T, dims=("x", "y"))
    corrected = normalize(square["reflectance"], classes, swapped, example_table()).reflectance
    np.testing.assert_array_equal(corrected.values, expected.values)
    with pytest.raises(InputError, match=r"classes has dims \('y', 'row'\)"):
        normalize(square["reflectance"], square["classes"].rename(x="row"), angles, example_table())


def test_a_declared_float_nodata_is_nodata_not_reflectance(scene):
    image = scene["reflectance"].copy()
    image[:, 3, 4] = -9999.0
    image.attrs["_FillValue"] = -9999.0
    result = normalize(image, scene["classes"], _angles(scene), example_table())
    assert np.isnan(result.reflectance.values[:, 3, 4]).all() and result.qa.values[3, 4] & 1  # QA nodata
    assert "_FillValue" not in result.reflectance.attrs
    clean = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table()).reflectance
    away = np.ones(image.shape[1:], bool)
    away[3, 4] = False
    np.testing.assert_array_equal(result.reflectance.values[:, away], clean.values[:, away])


def test_integer_counts_leave_no_packing_attribute_on_the_factors(scene):
    counts = np.round((scene["reflectance"].clip(0, 5) + 0.1) / 0.0001).astype(np.uint16)
    counts.attrs.update(scale_factor=0.0001, add_offset=-0.1, _FillValue=0, long_name="B04")
    corrected = normalize(counts, scene["classes"], _angles(scene), example_table()).reflectance
    # Left on the float output, a reader that decodes them would turn 0.07 into 0.07 * 1e-4 - 0.1.
    assert not {"scale_factor", "add_offset", "_FillValue"} & set(corrected.attrs)
    assert corrected.attrs["long_name"] == "B04" and corrected.attrs["brdf_input_scale"] == 0.0001


def test_floats_that_still_carry_a_scale_are_refused(scene):
    packed = np.round((scene["reflectance"].clip(0, 5) + 0.1) / 0.0001).astype(np.float32)
    packed.attrs.update(scale_factor=0.0001, add_offset=-0.1)  # open_rasterio(masked=True) reads counts so
    with pytest.raises(InputError, match="floats that still carry scale_factor=0.0001, add_offset=-0.1.*"
                                         "mask_and_scale=True"):
        normalize(packed, scene["classes"], _angles(scene), example_table())


def test_one_band_picked_from_a_series_is_refused_with_the_fix(scene):
    series = xr.concat([scene["reflectance"]] * 2, dim="time").isel(band=0)  # (time, y, x)
    with pytest.raises(InputError, match=r"dims \('time', 'y', 'x'\) and no band dimension.*expand_dims"):
        normalize(series, scene["classes"], _angles(scene), example_table())
    kept = scene["reflectance"].isel(band=0).expand_dims("band")  # one band, its wavelength a scalar
    alone = normalize(kept, scene["classes"], _angles(scene), example_table()).reflectance
    every = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table()).reflectance
    np.testing.assert_array_equal(alone.values[0], every.values[0])


def test_fit_classes_checks_its_inputs_as_normalize_does(scene):
    from brdfcorr.fit import fit_classes

    angles = xr.Dataset(_angles(scene))
    with pytest.raises(InputError, match="look like radians"):
        fit_classes(scene["reflectance"], scene["classes"], np.radians(angles), "ross_thick_li_sparse")
    counts = (scene["reflectance"] * 10000).astype(np.uint16)
    with pytest.raises(InputError, match=r"integer counts \(uint16\) without a scale_factor"):
        fit_classes(counts, scene["classes"], angles, "ross_thick_li_sparse")
    counts.attrs["scale_factor"] = 0.0001
    with pytest.raises(ParameterError, match="scale_factor=0.0001 and the sampling's reflectance_scale=0.0001"):
        fit_classes(counts, scene["classes"], angles, "ross_thick_li_sparse",
                    sampling=Sampling(reflectance_scale=0.0001))
    with pytest.raises(InputError, match="bands last"):
        fit_classes(scene["reflectance"].transpose("y", "x", "band"), scene["classes"], angles, "ross_thick_li_sparse")
    # Packed angles (uint16 hundredths with scale_factor 0.01) fit as the degrees they stand for.
    packed = xr.Dataset({name: np.round(layer * 100).astype(np.uint16).assign_attrs(scale_factor=0.01)
                         for name, layer in angles.items()})
    plain = fit_classes(scene["reflectance"], scene["classes"], angles, "ross_thick_li_sparse")
    unpacked = fit_classes(scene["reflectance"], scene["classes"], packed, "ross_thick_li_sparse")
    assert len(unpacked.fits) == len(plain.fits) == 4
    for mine, theirs in zip(unpacked.fits, plain.fits):
        for name in theirs.params:
            np.testing.assert_allclose(mine.params[name], theirs.params[name], rtol=1e-2, atol=1e-5)  # 0.01 deg


def test_band_centres_in_micrometres_or_stac_terms_are_read_in_nanometres(scene):
    # The coefficient set is per wavelength: the band centres choose each band's weights.
    nm = scene["reflectance"]
    expected = normalize(nm, None, _angles(scene), "roy2017", reference={"sza": 40.0}).reflectance
    centres = nm["wavelength"].values
    microns = nm.assign_coords(wavelength=("band", centres / 1000, {"units": "µm"}))
    # stackstac / odc-stac: no wavelength coordinate, eo:bands' center_wavelength [µm] instead.
    stac = nm.drop_vars("wavelength").assign_coords(center_wavelength=("band", centres / 1000))
    for cube in (microns, stac):
        corrected = normalize(cube, None, _angles(scene), "roy2017", reference={"sza": 40.0}).reflectance
        np.testing.assert_allclose(corrected.values, expected.values, rtol=1e-6)
    # Sentinel-2 band names as the band labels, as stackstac gives the assets' keys.
    named = nm.drop_vars("wavelength").assign_coords(band=["B02", "B03", "B04", "B08"])
    corrected = normalize(named, None, _angles(scene), "roy2017", reference={"sza": 40.0}).reflectance
    np.testing.assert_allclose(corrected["wavelength"].values, [492.4, 559.8, 664.6, 832.8])
    with pytest.raises(InputError, match="wavelength coordinate is in 'cm'"):
        normalize(nm.assign_coords(wavelength=("band", centres, {"units": "cm"})), None, _angles(scene), "roy2017")


def test_angles_on_the_images_coordinates_without_a_crs_are_on_its_grid(scene):
    bare = {name: layer.drop_vars("spatial_ref") for name, layer in _angles(scene).items()}
    assert all(layer.rio.crs is None for layer in bare.values()) and scene["reflectance"].rio.crs is not None
    corrected = normalize(scene["reflectance"], scene["classes"], bare, example_table()).reflectance
    expected = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table()).reflectance
    np.testing.assert_array_equal(corrected.values, expected.values)
    shifted = {name: layer.assign_coords(x=layer.x + 100.0) for name, layer in bare.items()}
    with pytest.raises(GridMismatchError, match="transform"):
        normalize(scene["reflectance"], scene["classes"], shifted, example_table())


def test_layers_cut_from_one_grid_with_other_rows_left_out_are_not_paired(scene):
    """Rows 0-7 and 16-23 of the image against rows 0-15 of the angles: the same first two
    coordinates, so rioxarray works out the same transform for both; the angles of rows 8-15 would
    correct rows 16-23 (a shift of 8 rows). The coordinates tell them apart."""
    rows = np.r_[0:8, 16:24]
    image, classes = scene["reflectance"].isel(y=rows), scene["classes"].isel(y=rows)
    angles = {name: layer.isel(y=slice(0, 16)) for name, layer in _angles(scene).items()}
    assert image.rio.transform() == angles["sza"].rio.transform()
    with pytest.raises(GridMismatchError, match=r"^sza is not on the grid of reflectance: its row coordinates differ "
                                                r"from position 8 on"):
        normalize(image, classes, angles, example_table())
    same_rows = {name: layer.isel(y=rows) for name, layer in _angles(scene).items()}
    assert np.isfinite(normalize(image, classes, same_rows, example_table()).reflectance.values).any()


def test_a_layer_whose_rows_run_the_other_way_is_named_so(scene):
    flipped = {name: layer.sortby("y") for name, layer in _angles(scene).items()}
    with pytest.raises(GridMismatchError, match=r"its rows run the other way .*sortby\('y', ascending=False\)"):
        normalize(scene["reflectance"], scene["classes"], flipped, example_table())


def test_a_scale_factor_that_is_a_divisor_is_refused(scene):
    # MODIS HDF files tag reflectance = counts / 10000 as scale_factor=10000; xarray and GDAL
    # multiply, so the corrected values would be ~1e7 (reflectance factors times 1e8).
    counts = np.round(scene["reflectance"].clip(0, 1) * 10000).astype(np.int16)
    counts.attrs.update(scale_factor=10000.0)
    with pytest.raises(InputError, match=r"scale_factor 10000: a divisor .*set scale_factor to 0\.0001"):
        normalize(counts, scene["classes"], _angles(scene), example_table())


def test_numpy_reflectance_with_dask_angles_is_corrected_as_all_numpy(scene):
    expected = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table())
    lazy_angles = {name: layer.chunk({"y": 12}) for name, layer in _angles(scene).items()}
    mixed = normalize(scene["reflectance"], scene["classes"], lazy_angles, example_table())
    np.testing.assert_array_equal(mixed.reflectance.values, expected.reflectance.values)
    np.testing.assert_array_equal(mixed.qa.values, expected.qa.values)


def test_angles_in_hundredths_of_a_degree_are_refused_as_the_cli_refuses_them(scene):
    # Every sun zenith outside [0, 90): each pixel would be invalid geometry, an all-NaN result.
    hundredths = {name: layer * 100 for name, layer in _angles(scene).items()}
    with pytest.raises(InputError, match=r"^angles: no sza value in \[0, 90\) deg \(found [0-9.]+\.\.[0-9.]+\); "
                                         r"are the angles scaled or in other units\?$"):  # no band-order hint
        normalize(scene["reflectance"], scene["classes"], hundredths, example_table())
    nan_sun = {**_angles(scene), "sza": xr.full_like(scene["sza"], np.nan)}
    with pytest.raises(InputError, match="no finite sza value"):
        normalize(scene["reflectance"], scene["classes"], nan_sun, example_table())
    # Dask layers by each chunk as it is corrected: the output was all NaN, flagged invalid geometry.
    lazy = normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"],
                     {name: layer.chunk({"y": 12}) for name, layer in hundredths.items()}, example_table())
    with pytest.raises(InputError, match=r"^angles \(a chunk\): no sza value in \[0, 90\) deg"):
        lazy.reflectance.compute()
    # A chunk without a finite sun zenith is nodata, not an error (its neighbours have them).
    partly = {**_angles(scene), "sza": scene["sza"].copy()}
    partly["sza"][:12] = np.nan  # the first chunk of rows
    normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"],
              {name: layer.chunk({"y": 12}) for name, layer in partly.items()}, example_table()).qa.compute()


@pytest.mark.parametrize("lazy", [False, True])
def test_angle_layers_of_packed_integers_are_unpacked(scene, lazy):
    # int16 hundredths with scale_factor 0.01 and a _FillValue, as xarray keeps them undecoded.
    expected = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table())
    packed = {}
    for name, layer in _angles(scene).items():
        stored = np.round(layer * 100).astype(np.int16 if name in ("sza", "vza") else np.uint16)
        stored.attrs.update(scale_factor=0.01, _FillValue=-1 if name in ("sza", "vza") else 65535)
        packed[name] = stored.chunk({"y": 12}) if lazy else stored
    corrected = normalize(scene["reflectance"], scene["classes"], packed, example_table())
    np.testing.assert_allclose(corrected.reflectance.values, expected.reflectance.values, rtol=1e-3)
    floats = {**_angles(scene), "sza": _angles(scene)["sza"].assign_attrs(scale_factor=0.01)}
    with pytest.raises(InputError, match="sza holds floats that still carry scale_factor=0.01"):
        normalize(scene["reflectance"], scene["classes"], floats, example_table())


def test_an_undeclared_fill_value_is_refused_numpy_at_once_dask_when_computed(scene):
    # -9999 that no nodata declares was multiplied by the factor (-11 235 out, no error); a
    # declared one stays nodata (test_a_declared_float_nodata_is_nodata_not_reflectance).
    filled = scene["reflectance"].copy()
    filled[:, :3, :3] = -9999.0
    with pytest.raises(InputError, match=r"reflectance: 36 values of a chunk lie below -0\.5.*-9999"):
        normalize(filled, scene["classes"], _angles(scene), example_table())
    lazy = normalize(filled.chunk({"y": 12}), scene["classes"], _angles(scene), example_table())
    with pytest.raises(InputError, match="-a_nodata -9999"):
        lazy.reflectance.compute()
    # Sentinel-2's -0.1 offset and atmospheric-correction noise over water stay above the floor.
    dark = scene["reflectance"].copy()
    dark[:, :3, :3] = -0.1
    normalize(dark, scene["classes"], _angles(scene), example_table())


def test_slope_and_aspect_in_radians_are_refused_as_by_the_command_line(scene):
    """The command line refuses slope and aspect files in radians (correction.terrain's
    check_slope_aspect); normalize took the same layers given in memory and corrected every pixel
    as if the ground were flat (37 % off on a field of slopes up to 40 deg), without a flag."""
    rng = np.random.default_rng(0)
    shape = scene["sza"].shape
    slope = scene["sza"].copy(data=np.radians(rng.uniform(0, 40, shape)))
    aspect = scene["sza"].copy(data=np.radians(rng.uniform(0, 360, shape)))
    with pytest.raises(InputError, match=r"^terrain layers: slope and aspect look like radians \(slope 0\.0"):
        normalize(scene["reflectance"], scene["classes"], {**_angles(scene), "slope": slope, "aspect": aspect},
                  example_table())
    degrees = {**_angles(scene), "slope": np.degrees(slope), "aspect": np.degrees(aspect)}
    assert np.isfinite(normalize(scene["reflectance"], scene["classes"], degrees, example_table()).reflectance).any()


@pytest.mark.parametrize("switch", ["flip_view_azimuth", "extrapolate"])
@pytest.mark.parametrize("value", ["no", "false", 0, None])
def test_a_switch_that_is_not_true_or_false_is_refused(scene, switch, value):
    # "no" and "false" are truthy: the view azimuths were turned by 180 deg (23 % off), silently.
    with pytest.raises(ParameterError, match=rf"^{switch} must be True or False, got {value!r}$"):
        normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table(), **{switch: value})


def test_no_class_map_with_a_table_of_several_classes_is_refused(scene):
    # classes=None makes every pixel class 1 (the roof tile of the example table): grass, paving
    # and soil were corrected as roof tile, 24 % off, without a flag.
    with pytest.raises(InputError, match=r"^classes=None makes the whole image class 1, and the table holds classes "
                                         r"\[1, 2, 3, 4\]: give the class map$"):
        normalize(scene["reflectance"], None, _angles(scene), example_table())
    one = ParameterTable.from_dict({"classes": [example_table().classes[0].model_dump()]})
    assert normalize(scene["reflectance"], None, _angles(scene), one).reflectance.notnull().any()


def test_a_scale_factor_per_band_is_refused_in_one_line(scene):
    counts = np.round(scene["reflectance"].clip(0, 1) * 10000).astype(np.int16)
    counts.attrs.update(scale_factor=[1e-4] * 4)  # was a bare TypeError from float()
    with pytest.raises(InputError, match=r"^reflectance carries scale_factor=\[0\.0001, .*one number is expected"):
        normalize(counts, scene["classes"], _angles(scene), example_table())


def test_a_wavelength_coordinate_in_micrometres_without_units_is_refused(scene):
    """0.48 ... 0.83 read as nm lie outside every table; the message offered extrapolate=True,
    which gave every band the table's 450 nm values (3 % off), silently."""
    microns = scene["reflectance"].assign_coords(wavelength=("band", scene["reflectance"]["wavelength"].values / 1e3))
    with pytest.raises(InputError, match=r"^the wavelength coordinate \(0\.48 \.\.\. 0\.83\) has no units and lies "
                                         r"below 100: micrometres\?"):
        normalize(microns, scene["classes"], _angles(scene), example_table(), extrapolate=True)
    microns["wavelength"].attrs["units"] = "um"
    expected = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table()).reflectance
    np.testing.assert_allclose(normalize(microns, scene["classes"], _angles(scene), example_table()).reflectance,
                               expected, rtol=1e-6)


def test_a_wavelength_coordinate_of_text_is_read_as_band_centres(scene):
    # '480 nm' (text, as some loaders label bands) raised a bare ValueError from float().
    centres = scene["reflectance"]["wavelength"].values
    expected = normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table()).reflectance
    for labels in ([f"{c:g} nm" for c in centres], [f"{c / 1e3:g} um" for c in centres], [f"{c:g}" for c in centres]):
        text = scene["reflectance"].assign_coords(wavelength=("band", labels))
        np.testing.assert_allclose(normalize(text, scene["classes"], _angles(scene), example_table()).reflectance,
                                   expected, rtol=1e-6)
    named = scene["reflectance"].assign_coords(wavelength=("band", ["blue", "green", "red", "nir"]))
    with pytest.raises(InputError, match=r"^the wavelength coordinate holds 'blue', no band centre"):
        normalize(named, scene["classes"], _angles(scene), example_table())


def test_a_sun_zenith_in_radians_beside_azimuths_in_degrees_is_warned_about(scene):
    """The radians rule needs every angle below 2 pi, and the azimuths in degrees exempt the
    layers: sza = arccos(mu0) in radians (0.52 ... 0.70) corrected as a sun at the zenith, 18 % off,
    silently. A sun within 1.6 deg of the zenith over a whole scene is rare: a warning, not an error."""
    angles = {**_angles(scene), "sza": np.radians(scene["sza"])}
    with pytest.warns(BrdfcorrWarning, match=r"^angles: the sun zenith lies in 0\.\d+\.\.0\.\d+ deg over the whole "
                                             r"scene: the sun within 0\.\d+ deg of the zenith, or radians\?"):
        normalize(scene["reflectance"], scene["classes"], angles, example_table())


def test_a_nodata_value_in_the_encoding_is_nodata(scene):
    """rio.write_nodata(value, encoded=True) keeps the value in the encoding (rioxarray's own
    nodata is then NaN, or an error for integers): the class map's nodata pixels were corrected as
    class 3 and a float image's fill value 65535 as a reflectance factor, with QA 0."""
    classes = scene["classes"]
    in_attrs = normalize(scene["reflectance"], classes.rio.write_nodata(3), _angles(scene), example_table())
    encoded = normalize(scene["reflectance"], classes.rio.write_nodata(3, encoded=True), _angles(scene),
                        example_table())
    np.testing.assert_array_equal(encoded.qa.values, in_attrs.qa.values)
    assert (encoded.qa.values[classes.values == 3] & int(QA.NO_CLASS)).all()
    filled = scene["reflectance"].copy()
    filled.values[:, 0, :5] = 65535.0
    corrected = normalize(filled.rio.write_nodata(65535.0, encoded=True), classes, _angles(scene), example_table())
    assert np.isnan(corrected.reflectance.values[:, 0, :5]).all()
    assert (corrected.qa.values[0, :5] & int(QA.NODATA)).all()
