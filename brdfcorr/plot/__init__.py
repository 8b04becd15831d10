"""Figures (matplotlib, no pyplot state): materials and class fits, goniometer fits, the papers'
analyses, and chain quicklooks. Functions return a :class:`matplotlib.figure.Figure`."""
