"""brdfcorr.analysis.assess and brdfcorr.plot.assess: closed forms, numpy computations, and a
leave-one-line-out run on lines rendered with a known model."""

import json

import dask.array as da
import numpy as np
import pytest
import xarray as xr

from brdfcorr.analysis.assess import (
    HoldoutFit,
    ViewAngleOptions,
    assess_overlap,
    assess_view_angles,
    leave_one_line_out,
    leave_one_line_out_report,
    overlap_report,
    signed_view_zenith,
    view_angle_report,
)
from brdfcorr.errors import BrdfcorrWarning, GridMismatchError, InputError
from brdfcorr.plot.assess import overlap_figure, profile_figure, write_assessment_figures
from brdfcorr.tasks.assess import Assessment, write_json
from brdfcorr.testing import synthetic_angles

NY, NX = 20, 40


@pytest.fixture
def geometry():
    """A push-broom line, vza 0-30 deg across x, sun due east (saa 90): one half forward, one back."""
    return synthetic_angles(NY, NX, vza_max=30.0, saa=90.0, dtype=np.float64)


@pytest.fixture
def class_map():
    return np.where(np.arange(NX)[None, :] % 2 == 0, 1, 2) * np.ones((NY, 1), dtype=np.int64)


def test_signed_view_zenith_by_sun_and_by_track():
    # Closed form: sun in the east (saa 90); a sensor east of the pixel (vaa 90) is on the sun's side
    # (backscatter, -), one west of it (vaa 270) opposite the sun (forward, +); perpendicular: 0.
    vza = np.array([20.0, 20.0, 20.0])
    vaa = np.array([90.0, 270.0, 0.0])
    np.testing.assert_array_equal(signed_view_zenith(vza, vaa, 90.0), [-20.0, 20.0, 0.0])
    # A line flown north: a pixel east of the track sees the sensor to its west (vaa 270): right, +.
    np.testing.assert_array_equal(signed_view_zenith(vza, vaa, by="track", heading=0.0), [-20.0, 20.0, 0.0])
    # Flown south, right is west.
    np.testing.assert_array_equal(signed_view_zenith(vza[:2], vaa[:2], by="track", heading=180.0), [20.0, -20.0])
    lazy = signed_view_zenith(da.from_array(vza, chunks=1), vaa, 90.0)
    assert isinstance(lazy, da.Array)
    np.testing.assert_array_equal(lazy.compute(), [-20.0, 20.0, 0.0])
    with pytest.raises(InputError, match="solar azimuth"):
        signed_view_zenith(vza, vaa)
    with pytest.raises(InputError, match="heading"):
        signed_view_zenith(vza, vaa, by="track")


def test_linear_scene_gives_its_slope_exactly_and_a_flat_one_slope_0_ratio_1(geometry, class_map, make_cube):
    signed = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    # Closed form: R = a + b * signed vza per class and band -> the least-squares slope is b.
    a = {1: (0.2, 0.05), 2: (0.4, 0.3)}
    b = {1: (0.003, -0.0005), 2: (-0.002, 0.001)}
    before = np.zeros((2, NY, NX))
    for class_id in (1, 2):
        for band in range(2):
            before[band][class_map == class_id] = (a[class_id][band] + b[class_id][band] * signed)[class_map == class_id]
    after = np.stack([np.where(class_map == 1, a[1][band], a[2][band]) for band in range(2)])  # flat
    result = assess_view_angles(make_cube(*before), make_cube(*after), class_map, geometry["vza"], geometry["vaa"],
                                geometry["saa"], options=ViewAngleOptions(class_names={1: "tile"}))
    np.testing.assert_allclose(result["slope"].sel(stage="before").values,
                               [[b[1][0], b[2][0]], [b[1][1], b[2][1]]], rtol=1e-10)
    np.testing.assert_allclose(result["slope"].sel(stage="after").values, 0.0, atol=1e-15)
    np.testing.assert_allclose(result["side_ratio"].sel(stage="after").values, 1.0, rtol=1e-12)
    # relative slope: 1000 b / mean R; the signed zeniths of a class are symmetric here, so mean R = a.
    mean = result["mean"].sel(stage="before").values
    np.testing.assert_allclose(result["relative_slope"].sel(stage="before").values,
                               1000 * result["slope"].sel(stage="before").values / mean, rtol=1e-12)
    # side ratio of the linear scene, independently: mean over + columns / mean over - columns.
    for index, class_id in enumerate((1, 2)):
        mask = class_map == class_id
        expected = before[0][mask & (signed > 0)].mean() / before[0][mask & (signed < 0)].mean()
        assert result["side_ratio"].sel(stage="before").values[0, index] == pytest.approx(expected, rel=1e-12)
    assert list(result["class_name"].values) == ["tile", "class 2"]
    assert result["pixels"].values.tolist() == [(class_map == 1).sum(), (class_map == 2).sum()]
    # profile: the bin means of a linear scene follow a + b * (bin mean of signed vza).
    profile = result["profile"].sel(stage="before", band=1).isel({"class": 0}).values
    edges = result["vza_bin_edges"].values
    mask = class_map == 1
    for k, (low, high) in enumerate(edges):
        inside = mask & (signed >= low) & (signed < high)
        if inside.any():
            assert profile[k] == pytest.approx(before[0][inside].mean(), rel=1e-12)
    assert result["bin_pixels"].values.sum() == mask.sum() + (class_map == 2).sum()


def test_dask_equals_numpy_and_pixels_invalid_in_either_stage_are_left_out(geometry, class_map):
    rng = np.random.default_rng(1)
    before = rng.uniform(0.1, 0.5, (3, NY, NX))
    after = before * rng.uniform(0.9, 1.1, (3, NY, NX))
    after[1, 3, 4] = np.nan  # one band NaN after: the pixel leaves both stages
    eager = assess_view_angles(before, after, class_map, geometry["vza"], geometry["vaa"], geometry["saa"])
    lazy = assess_view_angles(da.from_array(before, chunks=(3, 7, 9)), da.from_array(after, chunks=(1, 5, 5)),
                              da.from_array(class_map, chunks=6), geometry["vza"], geometry["vaa"], geometry["saa"])
    for name in ("slope", "side_ratio", "profile", "mean"):
        np.testing.assert_allclose(lazy[name].values, eager[name].values, rtol=1e-12, equal_nan=True)
    assert eager["pixels"].values.sum() == NY * NX - 1
    # mean against numpy over the same pixels
    valid = np.isfinite(after).all(axis=0) & (class_map == 1)
    assert float(eager["mean"].sel(stage="before").values[2, 0]) == pytest.approx(before[2][valid].mean(), rel=1e-12)


def _cluster_robust_slope_error(theta, values, blocks):
    """CR1 1-sigma of the least-squares slope of ``values`` on ``theta``, written out pixel by pixel
    and block by block (Cameron and Miller 2015, eq. 11): an independent computation."""
    x = theta - theta.mean()
    slope = (x * values).sum() / (x * x).sum()
    residuals = values - values.mean() - slope * x
    scores = np.array([(x[blocks == g] * residuals[blocks == g]).sum() for g in np.unique(blocks)])
    count = scores.size
    return np.sqrt(count / (count - 1) * (scores**2).sum()) / (x * x).sum()


def test_the_slope_error_is_cluster_robust_over_spatial_blocks(geometry, class_map):
    # Against the pixel-by-pixel CR1 on the same blocks (5 x 5 pixels here), numpy and dask (chunks
    # of whole blocks) alike; a block shared offset (correlated noise) shows in it.
    rng = np.random.default_rng(7)
    shared = np.kron(rng.normal(0, 0.02, (NY // 5, NX // 5)), np.ones((5, 5)))
    before = (0.3 + 0.001 * signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"]) + shared
              + rng.normal(0, 0.01, (NY, NX)))[None]
    options = ViewAngleOptions(block_size=5)
    eager = assess_view_angles(before, before, class_map, geometry["vza"], geometry["vaa"], geometry["saa"],
                               options=options)
    lazy = assess_view_angles(da.from_array(before, chunks=(1, 10, 20)), before, class_map, geometry["vza"],
                              geometry["vaa"], geometry["saa"], options=options)
    theta = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    rows, columns = np.indices((NY, NX))
    blocks = (rows // 5) * NX + columns // 5
    for index, class_id in enumerate((1, 2)):
        pick = class_map == class_id
        expected = _cluster_robust_slope_error(theta[pick], before[0][pick], blocks[pick])
        relative = 1000 * expected / before[0][pick].mean()
        for result in (eager, lazy):
            assert int(result["blocks"].values[index]) == len(np.unique(blocks[pick]))
            np.testing.assert_allclose(result["relative_slope_error"].values[:, 0, index], relative, rtol=1e-9)


@pytest.mark.parametrize("chunk", [16, 48, 512])
def test_the_slope_error_is_over_blocks_of_the_scene_whatever_the_chunking(chunk):
    # Blocks of 32 and 64 pixels counted from the scene's first pixel, as the report says, for
    # chunks smaller than a block (16), cutting blocks (48) and holding the scene (512): the
    # 1-sigma equals the pixel-by-pixel CR1 over those blocks. Before, blocks were cut at the
    # chunk's edges (chunks of 16: the 1-sigma of blocks of 16). 112 columns: the last blocks
    # are cut by the scene's edge.
    ny, nx, size = 96, 112, 32
    angles = synthetic_angles(ny, nx, vza_max=30.0, saa=90.0, dtype=np.float64)
    theta = signed_view_zenith(angles["vza"], angles["vaa"], angles["saa"])
    rng = np.random.default_rng(11)
    shared = np.kron(rng.normal(0, 0.02, (ny // 16, nx // 16)), np.ones((16, 16)))
    before = (0.3 + 0.001 * theta + shared + rng.normal(0, 0.01, (ny, nx)))[None]
    classes = np.where((np.arange(nx)[None, :] // 3) % 2 == 0, 1, 2) * np.ones((ny, 1), np.int64)
    result = assess_view_angles(da.from_array(before, chunks=(1, chunk, chunk)), before,
                                da.from_array(classes, chunks=chunk), angles["vza"], angles["vaa"], angles["saa"],
                                options=ViewAngleOptions(block_size=size))
    rows, columns = np.indices((ny, nx))
    for index, class_id in enumerate((1, 2)):
        pick = classes == class_id
        for position, side in enumerate((size, 2 * size)):
            blocks = (rows // side) * nx + columns // side
            expected = 1000 * _cluster_robust_slope_error(theta[pick], before[0][pick], blocks[pick]) \
                / before[0][pick].mean()
            np.testing.assert_allclose(result["relative_slope_error_blocks"].values[:, 0, index, position],
                                       expected, rtol=1e-9)
        assert int(result["blocks"].values[index]) == len(np.unique(((rows // size) * nx + columns // size)[pick]))


def test_the_slope_error_of_independent_pixels_is_the_classical_one():
    # White noise, blocks of 4 x 4 pixels (2500 of them): the cluster-robust 1-sigma of the
    # relative slope is within 10 % of the textbook sigma / sqrt(Sxx) (1000 / mean; sigma known).
    ny, nx, sigma = 200, 200, 0.01
    angles = synthetic_angles(ny, nx, vza_max=30.0, saa=90.0, dtype=np.float64)
    theta = signed_view_zenith(angles["vza"], angles["vaa"], angles["saa"])
    values = 0.3 + np.random.default_rng(3).normal(0, sigma, (1, ny, nx))
    tilted = values + 0.001 * theta  # before: a slope of 3.3 %/10 deg
    result = assess_view_angles(tilted, values, np.ones((ny, nx), np.int64), angles["vza"], angles["vaa"],
                                angles["saa"], options=ViewAngleOptions(block_size=4))
    textbook = 1000 * sigma / np.sqrt(((theta - theta.mean()) ** 2).sum()) / 0.3
    assert result["relative_slope_error"].values[1, 0, 0] == pytest.approx(textbook, rel=0.1)
    # The noise's own slope (this draw: -1.2 sigma) is within 2 sigma of 0, the tilt (348 sigma) is not.
    after = result["relative_slope"].values[1, 0, 0] / result["relative_slope_error"].values[1, 0, 0]
    assert abs(after) < 2
    assert view_angle_report(result)["summary"]["slopes_within_2_sigma"] == {"before": 0, "after": 1, "of": 1}


def test_view_angle_report_is_valid_json_with_null_for_nan(geometry, class_map, tmp_path):
    before = np.full((1, NY, NX), 0.3)
    classes = class_map.copy()
    classes[:, NX // 2:] = 0  # class 2 and 1 only on one side: the side ratio has no negative side -> NaN
    result = assess_view_angles(before, before, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                                options=ViewAngleOptions(class_ids=[1, 2]))
    report = view_angle_report(result)
    text = json.dumps(report, allow_nan=False)
    assert json.loads(text)["classes"][1]["pixels"] == int((classes == 2).sum())
    assert report["classes"][0]["before"]["side_ratio"] == [None]
    path = write_json(Assessment({"before": "x"}, result).report(), tmp_path / "r.json")
    assert json.loads(path.read_text())["kind"] == "brdfcorr assess"


def test_bad_input_is_one_clear_error(geometry, class_map):
    cube = np.ones((2, NY, NX))
    with pytest.raises(InputError, match="differ in shape"):
        assess_view_angles(cube, cube[:1], class_map, geometry["vza"], geometry["vaa"], geometry["saa"])
    with pytest.raises(GridMismatchError, match=r"the class map is not on the grid of reflectance: shape"):
        assess_view_angles(cube, cube, class_map[:5], geometry["vza"], geometry["vaa"], geometry["saa"])
    with pytest.raises(InputError, match="no class"):
        assess_view_angles(cube, cube, np.zeros_like(class_map), geometry["vza"], geometry["vaa"], geometry["saa"])
    with pytest.raises(InputError, match="bin width"):
        assess_view_angles(cube, cube, class_map, geometry["vza"], geometry["vaa"], geometry["saa"],
                           options=ViewAngleOptions(bin_width=0))


def test_inputs_are_read_as_normalize_reads_them(geometry, class_map):
    # assess_view_angles took its inputs by position as they were: int16 counts with a scale (before-
    # stage slopes 7 times too small), a class map and angles with rows running the other way
    # (another pixel's class), angles in radians or packed in hundredths of a degree.
    rng = np.random.default_rng(0)
    signed = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    values = 0.2 + 0.004 * signed + 0.01 * rng.standard_normal((2, NY, NX))
    y = 5400000.0 - 10.0 * np.arange(NY)
    cube = xr.DataArray(values, dims=("band", "y", "x"), coords={"y": y, "x": 10.0 * np.arange(NX)})
    layer = lambda array: xr.DataArray(array, dims=("y", "x"), coords={"y": y, "x": cube.x})  # noqa: E731
    angles = [layer(geometry[name]) for name in ("vza", "vaa", "saa")]
    expected = assess_view_angles(cube, cube, layer(class_map), *angles)["relative_slope"].values
    counts = cube.copy(data=np.round((values + 0.1) / 1e-4).astype(np.int16))
    counts.attrs.update(scale_factor=1e-4, add_offset=-0.1)
    scaled = assess_view_angles(counts, cube, layer(class_map), *angles)["relative_slope"].values
    np.testing.assert_allclose(scaled, expected, rtol=1e-3)
    ascending = [a.sortby("y") for a in (layer(class_map), *angles)]
    with pytest.raises(GridMismatchError, match="rows run the other way"):
        assess_view_angles(cube, cube, *ascending)
    with pytest.raises(InputError, match="the angles look like radians"):
        assess_view_angles(cube, cube, layer(class_map), *(a.copy(data=np.radians(a.values)) for a in angles))
    packed = [a.copy(data=np.round(a.values * 100).astype(np.int16)) for a in angles]
    for a in packed:
        a.attrs["scale_factor"] = 0.01
    np.testing.assert_allclose(assess_view_angles(cube, cube, layer(class_map), *packed)["relative_slope"].values,
                               expected, rtol=1e-2)


def test_overlap_metrics_against_numpy(make_cube, shifted):
    rng = np.random.default_rng(2)
    this_before = make_cube(*rng.uniform(0.1, 0.4, (2, NY, NX)))
    this_after = make_cube(*rng.uniform(0.1, 0.4, (2, NY, NX)))
    shift = 15
    other_before = shifted(make_cube(*rng.uniform(0.1, 0.4, (2, NY, NX))), shift)
    other_after = shifted(make_cube(*rng.uniform(0.1, 0.4, (2, NY, NX))), shift)
    other_after.values[0, 2, 1] = np.nan  # left out of every metric
    result = assess_overlap(this_before, this_after, other_before.chunk(8), other_after)
    # independent: the overlap is this line's columns shift.. and the other's 0..NX-shift
    for stage, this, other in (("before", this_before, other_before), ("after", this_after, other_after)):
        difference = other.values[:, :, :NX - shift] - this.values[:, :, shift:]
        valid = np.isfinite(other_after.values[:, :, :NX - shift]).all(axis=0)
        d = difference[:, valid]
        np.testing.assert_allclose(result["bias"].sel(stage=stage).values, d.mean(axis=1), rtol=1e-12)
        np.testing.assert_allclose(result["mad"].sel(stage=stage).values, np.abs(d).mean(axis=1), rtol=1e-12)
        np.testing.assert_allclose(result["rmse"].sel(stage=stage).values, np.sqrt((d**2).mean(axis=1)), rtol=1e-12)
        assert result["histogram"].sel(stage=stage).values.sum() == valid.sum()
    assert int(result["pixels"]) == NY * (NX - shift) - 1
    report = overlap_report(result)
    json.dumps(report, allow_nan=False)
    assert report["pixels"] == NY * (NX - shift) - 1
    with pytest.raises(InputError, match="do not overlap"):
        assess_overlap(this_before, this_after, shifted(other_before, NX), shifted(other_after, NX))


# ------------------------------------------------------------------- leave one line out
def test_leave_one_line_out_improves_the_held_out_metrics(make_lines):
    lines = make_lines()
    results = leave_one_line_out(lines, HoldoutFit("ross_thick_li_sparse", reference={"sza": 35.0, "vza": 0.0}),
                                 view_options=ViewAngleOptions(class_names={1: "grass", 2: "soil"}))
    assert [r.name for r in results] == ["line1", "line2", "line3"]
    for result in results:
        slope = np.abs(result.view["relative_slope"])
        # property: the held-out line's view-angle slope falls by far in every class and band
        # (not to 0: the texture makes the fit on two lines imperfect and has side differences of its own)
        assert (slope.sel(stage="after") < 0.2 * slope.sel(stage="before")).all(), result.name
        imbalance = np.abs(result.view["side_ratio"] - 1)
        assert (imbalance.sel(stage="after") < 0.2 * imbalance.sel(stage="before")).all(), result.name
        assert result.table.class_ids == (1, 2)  # both classes were fitted without the held-out line
        assert result.overlaps  # every line overlaps a neighbour
        for overlap in result.overlaps.values():
            assert (overlap["rmse"].sel(stage="after") < 0.2 * overlap["rmse"].sel(stage="before")).all()
    report = leave_one_line_out_report(results)
    json.dumps(report, allow_nan=False)
    assert set(report["lines"][1]["overlaps"]) == {"line1", "line3"}


def test_leave_one_line_out_corrects_both_lines_of_an_overlap_to_one_sun(make_lines):
    # Lines under suns of 30, 45 and 38 deg, the reference sun "mean" (the default): every line is
    # corrected to one sun, the mean of the lines' mean sun zeniths, (30 + 45 + 38) / 3 deg, so
    # every number equals a run given that sun. Before, each line went to its own scene mean and an
    # overlap's difference after held the BRDF between two suns (7-16 % instead of 0.003-1.3 %).
    lines = make_lines(szas=(30.0, 45.0, 38.0))
    common = (30.0 + 45.0 + 38.0) / 3
    mean = leave_one_line_out(lines, HoldoutFit("ross_thick_li_sparse"))
    fixed = leave_one_line_out(lines, HoldoutFit("ross_thick_li_sparse", reference={"sza": common, "vza": 0.0}))
    for by_mean, by_number in zip(mean, fixed):
        assert by_mean.reference == {"sza": pytest.approx(common, rel=1e-12), "vza": 0.0,
                                     "sza_from": "mean of the lines"}
        assert by_number.reference["sza_from"] == "fixed"
        assert set(by_mean.overlaps) == set(by_number.overlaps) and by_mean.overlaps
        for name, overlap in by_mean.overlaps.items():
            np.testing.assert_allclose(overlap["rmse"].values, by_number.overlaps[name]["rmse"].values, rtol=1e-9)
            # property: the correction takes the overlap difference down
            relative = overlap["relative_rmse"]
            assert (relative.sel(stage="after") < relative.sel(stage="before")).all(), (by_mean.name, name)
    report = leave_one_line_out_report(mean)
    assert report["lines"][0]["reference"]["sza_from"] == "mean of the lines"
    json.dumps(report, allow_nan=False)


def test_figures_are_drawn_and_written(geometry, class_map, tmp_path, make_cube, shifted):
    rng = np.random.default_rng(4)
    before = make_cube(*rng.uniform(0.1, 0.4, (2, NY, NX))).assign_coords(wavelength=("band", [560.0, 860.0]))
    after = before * 1.0
    view = assess_view_angles(before, after, class_map, geometry["vza"], geometry["vaa"], geometry["saa"],
                              options=ViewAngleOptions(class_names={1: "roof_tile", 2: "grass"}))
    figure = profile_figure(view)
    left = figure.axes[0]
    assert left.get_xlabel() == "signed view zenith [deg]"
    assert "560 nm" in left.get_title()  # the default band: nearest 660 nm (|560 - 660| < |860 - 660|)
    labels = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "roof tile before" in labels and "grass after" in labels  # names as people read them
    # The slope panel: each class and stage a line with its 1-sigma as bars, as the report gives them.
    right = profile_figure(view, title="line_09").axes[1]
    assert right.get_title().startswith("line_09 view-angle slope") and "±1σ" in right.get_title()
    assert len(right.containers) == 2 * view.sizes["class"]
    for container, (index, stage) in zip(right.containers, [(i, s) for i in range(2) for s in ("before", "after")],
                                         strict=True):
        values = view.isel({"class": index}).sel(stage=stage)
        segments = np.array(container.lines[2][0].get_segments())  # (band, [low, high], [x, y])
        np.testing.assert_allclose(segments[:, 0, 1], values["relative_slope"] - values["relative_slope_error"])
        np.testing.assert_allclose(segments[:, 1, 1], values["relative_slope"] + values["relative_slope_error"])
        assert values["relative_slope_error"].min() > 0
    overlap = assess_overlap(before, after, shifted(before, 10), shifted(after, 10))
    assert overlap_figure(overlap).axes[0].get_xlabel().endswith("[reflectance, 1]")
    written = write_assessment_figures(Assessment({}, view, overlap), tmp_path / "figures")
    assert [p.name for p in written] == ["assess_profiles.png", "assess_overlap.png"]
    assert all(p.read_bytes().startswith(b"\x89PNG") for p in written)


def test_a_class_seen_over_a_narrow_view_range_is_named_in_a_warning(geometry, make_cube):
    """A class seen only near nadir gets a slope per 10 deg extrapolated from a few degrees (issue 38:
    "43.51 ± 77.12 %/10°" from a 3°-wide range without a word); its range is the span of its bins."""
    from brdfcorr.analysis.view_angles import NARROW_RANGE, view_angle_report

    signed = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    classes = np.where(np.abs(signed) < 4.0, 2, 1)
    cube = make_cube(0.2 + 0.001 * signed, 0.3 + 0.002 * signed)
    options = ViewAngleOptions(class_names={1: "wide", 2: "nadir"})
    with pytest.warns(BrdfcorrWarning, match=r"less than 10 deg of view zenith: nadir \((?P<range>[\d.]+) deg\)"):
        result = assess_view_angles(cube, cube, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                                    options=options)
    width = options.bin_width  # independently: the bins of width bin_width that hold the class's zeniths
    inside = signed[classes == 2]
    expected = (np.floor(inside.max() / width) + 1 - np.floor(inside.min() / width)) * width
    report = view_angle_report(result)
    ranges = {entry["name"]: entry["view_zenith_range_deg"] for entry in report["classes"]}
    assert ranges["nadir"] == pytest.approx(expected) and ranges["nadir"] < NARROW_RANGE
    assert ranges["wide"] > NARROW_RANGE
    assert "nadir (" in report["errors"]["narrow"] and "wide (" not in report["errors"]["narrow"]


def test_the_narrow_range_is_judged_from_the_pixels_not_the_bins(geometry, make_cube):
    # With bins 10 deg wide a class within 4 deg of nadir spans two bins (20 deg) and was never
    # named; its pixels' spread, sqrt(12) x the standard deviation of their signed view zenith
    # (computed here with numpy), is below 10 deg.
    signed = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    classes = np.where(np.abs(signed) < 4.0, 2, 1)
    cube = make_cube(0.2 + 0.001 * signed, 0.3 + 0.002 * signed)
    options = ViewAngleOptions(class_names={1: "wide", 2: "nadir"}, bin_width=10.0)
    with pytest.warns(BrdfcorrWarning, match=r"less than 10 deg of view zenith: nadir \([\d.]+ deg\);"):
        result = assess_view_angles(cube, cube, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                                    options=options)
    expected = [np.sqrt(12.0) * np.std(signed[classes == class_id]) for class_id in (1, 2)]
    np.testing.assert_allclose(result["vza_width"].values, expected, rtol=1e-9)


@pytest.mark.parametrize("lazy", [False, True])
def test_the_slope_error_of_a_class_far_from_nadir_with_small_residuals_is_exact(lazy):
    # Signed zeniths 50-55 deg, reflectance 0.5 with noise 1e-5: from uncentred block sums the
    # 1-sigma lost its digits to cancellation (4.8x too large at blocks of 128 pixels; its growth
    # to twice the block 2.2 instead of 1.35, past the warning's limit).
    n, size = 256, 64
    theta = np.tile(np.linspace(50, 55, n), (n, 1))
    vaa, saa = np.full((n, n), 180.0), np.zeros((n, n))  # all forward scattering: signed = +vza
    values = (0.5 + 1e-5 * np.random.default_rng(0).standard_normal((n, n)))[None]
    cube = da.from_array(values, chunks=(1, 96, 96)) if lazy else values
    result = assess_view_angles(cube, cube, np.ones((n, n), np.int64), theta, vaa, saa,
                                options=ViewAngleOptions(block_size=size))
    rows, columns = np.indices((n, n))
    for position, side in enumerate((size, 2 * size)):
        expected = 1000 * _cluster_robust_slope_error(theta.ravel(), values[0].ravel(),
                                                      ((rows // side) * n + columns // side).ravel()) / 0.5
        np.testing.assert_allclose(result["relative_slope_error_blocks"].values[0, 0, 0, position], expected,
                                   rtol=1e-6)


def test_a_class_with_a_negative_mean_keeps_its_relative_slope():
    # Dark water after Sentinel-2's -0.1 offset: a mean of -0.01. The relative slope is 1000 b / |mean|
    # (it was NaN, and the class left the count of slopes within 2 sigma).
    angles = synthetic_angles(NY, NX, vza_max=30.0, saa=90.0, dtype=np.float64)
    theta = signed_view_zenith(angles["vza"], angles["vaa"], angles["saa"])
    cube = np.stack([0.2 + 0.001 * theta, -0.01 + 0.0001 * theta])
    result = assess_view_angles(cube, cube, np.ones((NY, NX), np.int64), angles["vza"], angles["vaa"],
                                angles["saa"])
    slope, mean = result["slope"].values[0, :, 0], result["mean"].values[0, :, 0]
    np.testing.assert_allclose(slope, [0.001, 0.0001], rtol=1e-9)
    np.testing.assert_allclose(result["relative_slope"].values[0, :, 0], 1000 * slope / np.abs(mean), rtol=1e-12)
    assert result["relative_slope"].values[0, 1, 0] > 0  # brighter on the positive side, as the slope says


def test_class_ids_that_are_not_whole_numbers_are_refused(geometry):
    classes = np.where(np.arange(NX)[None, :] < NX // 2, 1.0, 1.5) * np.ones((NY, 1))
    cube = np.full((1, NY, NX), 0.3)
    with pytest.raises(InputError, match=r"class ids are whole numbers; the class map holds 1\.5"):
        assess_view_angles(cube, cube, classes, geometry["vza"], geometry["vaa"], geometry["saa"])


def test_a_bin_width_whose_profiles_would_not_fit_in_memory_is_refused(geometry):
    # 120 bands, 2 classes, bins of 0.01 deg (18 000): 2 x 120 x 2 x 18 000 float64 = 66 MiB in
    # every chunk's sums (a 425-band line with 20 classes: 2.4 GB).
    cube = np.full((120, NY, NX), 0.3)
    classes = np.where(np.arange(NX)[None, :] % 2 == 0, 1, 2) * np.ones((NY, 1), np.int64)
    with pytest.raises(InputError, match=r"bin width 0\.01 deg: the profiles of 120 bands and 2 classes would take "
                                         r"66 MiB .*at least 0\.02 deg"):
        assess_view_angles(cube, cube, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                           options=ViewAngleOptions(bin_width=0.01))
    assess_view_angles(cube, cube, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                       options=ViewAngleOptions(bin_width=0.02))
