"""The chain quicklook: the legend names the table's classes, up to six of them."""

import numpy as np

from brdfcorr.plot.quicklook import quicklook_figure


def test_legend_names_the_most_frequent_classes():
    rng = np.random.default_rng(0)
    class_map = rng.choice(np.arange(0, 8), size=(30, 40), p=[0.02, 0.3, 0.2, 0.15, 0.12, 0.1, 0.08, 0.03])
    cube = rng.uniform(0.05, 0.3, (3, 30, 40))
    names = {1: "roof_tile", 2: "concrete", 3: "grass", 4: "trees", 5: "soil", 6: "water", 7: "rare"}
    figure = quicklook_figure(cube, cube * 0.9, class_map=class_map.astype(float), class_names=names)
    labels = [text.get_text() for text in figure.axes[-1].get_legend().get_texts()]
    shown = {label.rsplit(" ", 1)[0] for label in labels}
    assert shown == {"roof_tile", "concrete", "grass", "trees", "soil", "water"}  # the 6 most frequent
    assert len(labels) == 12  # before and after for each
