"""The materials figure (``brdfcorr demo``'s materials_brdf.png, issue 38): its legend hides no
axis label, tick label or title, and lies within the figure (extents as the renderer draws them)."""

from __future__ import annotations

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from brdfcorr.models.materials import load_material, material_names
from brdfcorr.plot.materials import plot_materials


@pytest.mark.parametrize("count", [1, 5])
def test_the_legend_overlaps_no_axis_label(count):
    materials = [load_material(name) for name in material_names()][:count]
    figure = plot_materials(materials)
    renderer = FigureCanvasAgg(figure).get_renderer()
    figure.draw(renderer)  # the constrained layout places the legend and the panels
    legend, = figure.legends
    box = legend.get_window_extent(renderer)
    assert [text.get_text() for text in legend.get_texts()] == [material.label for material in materials]
    figure_box = figure.bbox
    assert figure_box.x0 <= box.x0 and box.x1 <= figure_box.x1 and figure_box.y0 <= box.y0 and box.y1 <= figure_box.y1
    for axis in figure.axes:
        texts = [axis.xaxis.label, axis.yaxis.label, axis.title, *axis.get_xticklabels(), *axis.get_yticklabels()]
        for text in texts:
            if text.get_text() and text.get_visible():
                assert not text.get_window_extent(renderer).overlaps(box), text.get_text()
        assert not axis.get_window_extent(renderer).overlaps(box), axis.get_title()
