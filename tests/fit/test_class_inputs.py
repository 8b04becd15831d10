"""What an imagery fit makes of inputs that hold less than its settings expect: a band without a
finite value in one small class (that class fails, the others are fitted) or in every class (the
band is bad for the image), and class settings that name classes no class map holds."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

from brdfcorr.errors import GridMismatchError, InputError
from brdfcorr.fit.classes import ClassFitWarning, ClassModels, GuardRails, fit_classes
from brdfcorr.params import ParameterTable
from brdfcorr.testing import synthetic_scene

WAVELENGTHS = (480.0, 560.0, 660.0, 830.0)
KERNELS = ParameterTable(classes=[
    {"id": ident, "name": name, "model": "ross_thick_li_sparse", "wavelengths": list(WAVELENGTHS),
     "params": {"f_iso": [0.03, 0.06, 0.04, 0.35], "f_vol": [0.015, 0.03, 0.02, 0.2],
                "f_geo": [0.003, 0.006, 0.004, 0.03]}}
    for ident, name in ((1, "veg"), (2, "soil"))])
GUARD = GuardRails(min_samples=100)


def _scene(small_class: bool = True):
    """A line of classes 1 and 2 (4x4-pixel patches), with class 7 on 20 pixels (4 x 5) in a corner."""
    scene = synthetic_scene(48, 64, wavelengths=WAVELENGTHS, table=KERNELS, dtype=np.float64)
    classes = scene["classes"].copy()
    if small_class:
        classes[0:4, 0:5] = 7
    angles = xr.Dataset({name: scene[name] for name in ("sza", "saa", "vza", "vaa")})
    return scene["reflectance"].copy(), classes, angles


def test_a_band_empty_in_one_small_class_fails_that_class_only():
    """Band 2 is NaN at class 7's 20 pixels only: class 7 is left uncorrected with a warning that
    names it and the band; classes 1 and 2 (about 1500 pixels each) are fitted as without it."""
    image, classes, angles = _scene()
    image[1, 0:4, 0:5] = np.nan
    with pytest.warns(ClassFitWarning, match=r"class 7 \(class_7\): band 2 \(560 nm\): no finite reflectance at any "
                                             r"of the class's 20 sampled pixels"):
        result = fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse"), guard=GUARD)
    status = {fit.class_id: fit.status for fit in result.fits}
    assert status == {1: "fitted", 2: "fitted", 7: "uncorrected"}
    assert result.table.class_ids == (1, 2)
    with pytest.warns(ClassFitWarning, match=r"class 7 \(class_7\): 20 samples < 100"):  # too small in any case
        clean = fit_classes(*_scene(), ClassModels("ross_thick_li_sparse"), guard=GUARD)
    for fit, expected in zip(result.fits[:2], clean.fits[:2]):
        for name, values in expected.params.items():
            np.testing.assert_array_equal(fit.params[name], values)


def test_a_band_empty_in_every_class_is_refused_for_the_image():
    image, classes, angles = _scene()
    image[2] = np.nan
    with pytest.raises(InputError, match=r"^band 3 \(660 nm\): no finite reflectance at any sampled pixel of any "
                                         r"class \(3 classes; .*leave the band out of the image$"):
        fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse"), guard=GUARD)


def test_class_settings_for_classes_the_fit_does_not_have_are_named():
    image, classes, angles = _scene(small_class=False)
    models = ClassModels("ross_thick_li_sparse", class_models={9: "rpv", 1: "ross_thin_li_sparse"},
                         names={9: "foo", 12: "bar", 2: "soil"}, fallback={9: "roy2016"})
    with pytest.warns(ClassFitWarning, match=r"^the class settings name classes 9, 12 that no class map holds "
                                             r"\(class_models 9; names 9, 12; fallback 9\): not used$"):
        result = fit_classes(image, classes, angles, models, guard=GUARD)
    assert [(fit.model, fit.name) for fit in result.fits] == [("ross_thin_li_sparse", "class_1"),
                                                              ("ross_thick_li_sparse", "soil")]
    chosen = ClassModels("ross_thick_li_sparse", names={2: "soil"}, class_ids=[1])
    with pytest.warns(ClassFitWarning, match=r"name class 2 that the class_ids leave out \(names 2\)"):
        fit_classes(image, classes, angles, chosen, guard=GUARD)


def test_class_settings_of_classes_fitted_give_no_warning():
    image, classes, angles = _scene(small_class=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ClassFitWarning)
        # default_names (a strata map's tags, a chain's table) describe what a map may hold: not checked
        fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse", names={1: "veg", 2: "soil"},
                                                        default_names={5: "water"}), guard=GUARD)


@pytest.mark.parametrize("layer", ["classes", "angles"])
def test_layers_off_the_images_grid_are_refused_as_by_a_correction(layer):
    """The sampler pairs image, class map and angles pixel by pixel: a layer whose rows run the
    other way (same labels, another order) would be fitted against the wrong pixels' angles or
    classes (f_geo of both classes 0, f_vol/f_iso off by 2.4x and 13x, without a warning)."""
    image, classes, angles = _scene(small_class=False)
    inputs = {"classes": classes, "angles": angles}
    inputs[layer] = inputs[layer].sortby("y")
    with pytest.raises(GridMismatchError, match=r"rows run the other way"):
        fit_classes(image, inputs["classes"], inputs["angles"], ClassModels("ross_thick_li_sparse"), guard=GUARD)
    same = fit_classes(image.sortby("y"), classes.sortby("y"), angles.sortby("y"), ClassModels("ross_thick_li_sparse"),
                       guard=GUARD)
    canonical = fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse"), guard=GUARD)
    for flipped, expected in zip(same.fits, canonical.fits):
        assert flipped.status == expected.status == "fitted"
        for name, values in expected.params.items():
            np.testing.assert_allclose(flipped.params[name], values, rtol=0.05)


def test_a_sampling_switch_that_is_not_true_or_false_is_refused():
    from brdfcorr.errors import ParameterError
    from brdfcorr.fit import Sampling

    with pytest.raises(ParameterError, match=r"^flip_view_azimuth must be True or False, got 'no'$"):
        fit_classes(*_scene(small_class=False), ClassModels("ross_thick_li_sparse"), guard=GUARD,
                    sampling=Sampling(flip_view_azimuth="no"))


def test_a_class_map_with_its_nodata_in_the_encoding_leaves_those_pixels_out():
    """rio.write_nodata(7, encoded=True) on an integer map: rioxarray's own nodata is an error
    there (NaN into an integer); the fit failed with a bare ValueError or sampled class 7."""
    image, classes, angles = _scene()
    in_attrs = fit_classes(image, classes.rio.write_nodata(7), angles, ClassModels("ross_thick_li_sparse"), guard=GUARD)
    encoded = fit_classes(image, classes.rio.write_nodata(7, encoded=True), angles, ClassModels("ross_thick_li_sparse"),
                          guard=GUARD)
    assert [fit.class_id for fit in encoded.fits] == [fit.class_id for fit in in_attrs.fits] == [1, 2]
    for fit, expected in zip(encoded.fits, in_attrs.fits):
        for name, values in expected.params.items():
            np.testing.assert_array_equal(fit.params[name], values)


def test_scenes_are_paired_band_by_band_by_their_wavelengths():
    """Two views of one scene, the second with its bands stored in another order: the pooled fit
    paired them by position (class 1's f_vol/f_iso 0.16 and 0 for 0.5 and 0.5 at the outer bands,
    without a word). Other bands, or another count, are refused."""
    image, classes, angles = _scene(small_class=False)
    models = ClassModels("ross_thick_li_sparse")
    canonical = fit_classes([image, image], [classes, classes], [angles, angles], models, guard=GUARD)
    shuffled = image.isel(band=[2, 0, 3, 1])
    paired = fit_classes([image, shuffled], [classes, classes], [angles, angles], models, guard=GUARD)
    for fit, expected in zip(paired.fits, canonical.fits):
        for name, values in expected.params.items():
            np.testing.assert_allclose(fit.params[name], values, rtol=1e-9)
    with pytest.raises(InputError, match=r"^scene 2 has 3 bands, scene 1 has 4$"):
        fit_classes([image, image.isel(band=[0, 1, 2])], [classes, classes], [angles, angles], models, guard=GUARD)
    moved = image.assign_coords(wavelength=("band", [490.0, 560.0, 660.0, 830.0]))
    with pytest.raises(InputError, match=r"^scene 2 has its bands at 490, 560, 660, 830 nm, scene 1 at 480, 560, "
                                         r"660, 830 nm: not the same bands$"):
        fit_classes([image, moved], [classes, classes], [angles, angles], models, guard=GUARD)


def test_scenes_with_the_same_coordinates_in_two_crs_are_not_one_grid():
    """The same numbers in UTM zones 32 and 33 are ground 600 km apart: the scenes were taken
    for one grid, and each pixel's level was fitted from two unrelated pixels."""
    from brdfcorr.fit.sampling import sample_classes

    image, classes, angles = _scene(small_class=False)
    there = [layer.rio.write_crs("EPSG:32633") for layer in (image, classes, angles)]
    same = sample_classes([image, image], [classes, classes], [angles, angles])
    apart = sample_classes([image, there[0]], [classes, there[1]], [angles, there[2]])
    assert {samples.levels for samples in same.values()} == {"pixel"}
    assert {samples.levels for samples in apart.values()} == {"pooled"}


def test_scenes_without_a_crs_taken_as_one_grid_are_warned_about():
    """Raw lines cut to one size are other ground: without a CRS the sampler takes them for one
    grid and frees each pixel's level across them, which it did without a word."""
    import warnings

    from brdfcorr.errors import BrdfcorrWarning
    from brdfcorr.fit.sampling import sample_classes

    image, classes, angles = _scene(small_class=False)
    bare = [layer.drop_vars("spatial_ref") for layer in (image, classes, angles)]
    assert bare[0].rio.crs is None
    with pytest.warns(BrdfcorrWarning, match=r"^the 2 scenes have no CRS: taken as one grid by their shape"):
        samples = sample_classes([bare[0], bare[0]], [bare[1], bare[1]], [bare[2], bare[2]])
    assert {entry.levels for entry in samples.values()} == {"pixel"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", BrdfcorrWarning)
        sample_classes([image, image], [classes, classes], [angles, angles])


def test_dims_named_as_loaders_name_them_fit_as_the_canonical_ones():
    # A 'bands' band dim or 'lat'/'lon' spatial dims, which normalize takes, failed with xarray's
    # own "Dimensions {'band'} do not exist": the sampler used the names band, y and x.
    image, classes, angles = _scene(small_class=False)
    models = ClassModels("ross_thick_li_sparse")
    canonical = fit_classes(image, classes, angles, models, guard=GUARD)
    assert all(fit.status == "fitted" for fit in canonical.fits)
    renamed = fit_classes(image.rename(band="bands", y="lat", x="lon"), classes.rename(y="lat", x="lon"),
                          angles.rename(y="lat", x="lon"), models, guard=GUARD)
    for fit, expected in zip(renamed.fits, canonical.fits):
        for name, values in expected.params.items():
            np.testing.assert_array_equal(fit.params[name], values)
