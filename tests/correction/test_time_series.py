"""A (time, band, y, x) cube through the ``.brdf`` accessor (issue 38): date by date, lazily, each
date exactly as the same image alone; class maps and angles with or without the time dimension."""

from __future__ import annotations

import dask.array
import numpy as np
import pandas as pd
import pytest
import xarray as xr

import brdfcorr  # noqa: F401  (registers the .brdf accessor)
from brdfcorr.correction import normalize
from brdfcorr.errors import InputError
from brdfcorr.testing import example_table, synthetic_angles, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")
DATES = pd.date_range("2024-05-01", periods=3, freq="5D")


@pytest.fixture(scope="module")
def scenes():
    return [synthetic_scene(ny=16, nx=20, seed=i, angles=synthetic_angles(16, 20, sza=(20.0 + 8 * i, 30.0 + 8 * i)))
            for i in range(len(DATES))]


def _stack(layers):
    return xr.concat(layers, dim=pd.Index(DATES, name="time"))


@pytest.mark.parametrize("reference", [{"sza": "mean"}, {"sza": 40.0, "vza": 0.0}])
def test_a_cube_with_time_is_normalized_date_by_date_lazily(scenes, reference):
    cube = _stack([s["reflectance"] for s in scenes]).chunk({"y": 8})
    angles = xr.Dataset({name: _stack([s[name] for s in scenes]) for name in ANGLES}).chunk({"y": 8})
    classes = _stack([s["classes"] for s in scenes])
    corrected, qa = cube.brdf.normalize(classes, angles, example_table(), reference=reference)
    assert isinstance(corrected.data, dask.array.Array) and isinstance(qa.data, dask.array.Array)
    assert corrected.dims == ("time", "band", "y", "x") and qa.dims == ("time", "y", "x")
    assert list(corrected["time"].values) == list(DATES.values)
    for index, scene in enumerate(scenes):
        alone = normalize(scene["reflectance"], scene["classes"], {n: scene[n] for n in ANGLES}, example_table(),
                          reference=reference)
        np.testing.assert_array_equal(corrected.isel(time=index).values, alone.reflectance.values)
        np.testing.assert_array_equal(qa.isel(time=index).values, alone.qa.values)


def test_a_coefficient_set_without_a_class_map_and_one_class_map_for_all_dates(scenes):
    cube = _stack([s["reflectance"] for s in scenes])
    angles = {name: _stack([s[name] for s in scenes]).values for name in ANGLES}  # numpy (time, y, x)
    nbar, qa = cube.brdf.normalize(None, angles, "roy2017", reference={"sza": 45.0})
    assert (qa.values == 0).all()
    one_map = cube.brdf.normalize(xr.ones_like(scenes[0]["classes"]), angles, "roy2017", reference={"sza": 45.0})
    np.testing.assert_array_equal(nbar.values, one_map.reflectance.values)
    first = normalize(scenes[0]["reflectance"], None, {n: scenes[0][n] for n in ANGLES}, "roy2017",
                      reference={"sza": 45.0})
    np.testing.assert_array_equal(nbar.isel(time=0).values, first.reflectance.values)


def test_dated_layers_are_paired_with_the_cubes_dates_by_label(scenes):
    cube = _stack([s["reflectance"] for s in scenes])
    angles = xr.Dataset({name: _stack([s[name] for s in scenes]) for name in ANGLES})
    classes = _stack([s["classes"] for s in scenes])
    table, reference = example_table(), {"sza": 40.0}
    # A cloudy date dropped from the cube only, the angles given in reverse order: each date
    # still takes its own angles and class map.
    kept = cube.sel(time=[DATES[0], DATES[2]])
    result = kept.brdf.normalize(classes.isel(time=[2, 1, 0]), angles.isel(time=[2, 1, 0]), table, reference=reference)
    alone = normalize(scenes[2]["reflectance"], scenes[2]["classes"], {n: scenes[2][n] for n in ANGLES}, table,
                      reference=reference).reflectance
    np.testing.assert_array_equal(result.reflectance.sel(time=DATES[2]).values, alone.values)
    with pytest.raises(InputError, match="angles has no time 2024-05-11"):
        cube.brdf.normalize(classes, angles.isel(time=[0, 1]), table)
    unlabelled = {name: np.stack([s[name].values for s in scenes[:2]]) for name in ANGLES}
    with pytest.raises(InputError, match="reflectance has 3 dates along 'time' and sza 2"):
        cube.brdf.normalize(classes, unlabelled, table)


def test_repeated_dates_pair_by_position_where_the_labels_are_the_same(scenes):
    # Two granules of one datetime (a stackstac stack of adjacent tiles): the angle layers carry the
    # same labels, so each date takes its own angles, as when the labels are dropped.
    dates = pd.Index([DATES[0], DATES[0], DATES[2]], name="time")
    cube = xr.concat([s["reflectance"] for s in scenes], dim=dates)
    angles = xr.Dataset({name: xr.concat([s[name] for s in scenes], dim=dates) for name in ANGLES})
    table, reference = example_table(), {"sza": 40.0}
    result = cube.brdf.normalize(scenes[0]["classes"], angles, table, reference=reference)
    by_position = cube.brdf.normalize(scenes[0]["classes"], angles.drop_vars("time"), table, reference=reference)
    np.testing.assert_array_equal(result.reflectance.values, by_position.reflectance.values)
    with pytest.raises(InputError, match="reflectance repeats time 2024-05-01"):
        cube.brdf.normalize(scenes[0]["classes"], angles.isel(time=[2, 1, 0]), table, reference=reference)


@pytest.mark.parametrize("order", [("band", "y", "x", "time"), ("time", "y", "x", "band"), ("y", "x", "time", "band")])
def test_a_cube_in_another_order_is_told_the_transpose_that_orders_it(scenes, order):
    cube = _stack([s["reflectance"] for s in scenes]).transpose(*order)
    with pytest.raises(InputError, match=r"reflectance.transpose\('time', 'band', 'y', 'x'\)"):
        cube.brdf.normalize(scenes[0]["classes"], {n: scenes[0][n] for n in ANGLES}, example_table())


def test_dated_layers_along_another_dimension_name_the_rename(scenes):
    # Angles stacked along 'date' for a cube along 'time': the message said "sza must be 2-D (y, x)".
    cube = _stack([s["reflectance"] for s in scenes])
    angles = xr.Dataset({name: _stack([s[name] for s in scenes]) for name in ANGLES}).rename(time="date")
    with pytest.raises(InputError, match=r"angles has a dimension 'date' \(3 items\).*angles.rename\(date='time'\)"):
        cube.brdf.normalize(scenes[0]["classes"], angles, example_table())
    classes = _stack([s["classes"] for s in scenes]).rename(time="date")
    with pytest.raises(InputError, match=r"classes.rename\(date='time'\)"):
        cube.brdf.normalize(classes, angles.rename(date="time"), example_table())
    # Renamed as told, it runs as the cube along 'time' does.
    renamed = cube.brdf.normalize(scenes[0]["classes"], angles.rename(date="time"), example_table())
    assert renamed.reflectance.dims == ("time", "band", "y", "x")
