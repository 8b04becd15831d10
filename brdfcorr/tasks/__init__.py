"""Whole tasks on files: one library function per CLI command, shared with the chains.

- :mod:`~brdfcorr.tasks.correct`: correct an image file (:func:`~brdfcorr.tasks.correct.correct_files`
  of a :class:`~brdfcorr.tasks.request.CorrectionRequest`);
- :mod:`~brdfcorr.tasks.goniometer`: fit a goniometer table; :mod:`~brdfcorr.tasks.fit`: fit classes from scenes;
- :mod:`~brdfcorr.tasks.assess`: assess a correction, leave one line out;
- :mod:`~brdfcorr.tasks.nbar`, :mod:`~brdfcorr.tasks.hls`: NBAR of Sentinel-2 / Landsat folders and HLS granules;
- :mod:`~brdfcorr.tasks.series`: a time series of such folders as one lazy cube for notebooks;
- :mod:`~brdfcorr.tasks.classmaps`: NDVI strata and land-cover maps as class-map files;
- :mod:`~brdfcorr.tasks.results`: what the correction and NBAR tasks return
  (:class:`~brdfcorr.tasks.results.CorrectionResult`, :class:`~brdfcorr.tasks.results.NbarResult`).

A task never imports :mod:`brdfcorr.chain` (import-linter's layers contract).
"""

#: The task modules, imported at first use as ``brdfcorr.tasks.<name>`` (importing this package
#: loads none of them: the command line pays only for the task it runs).
__all__ = ["assess", "classmaps", "correct", "fit", "goniometer", "hls", "nbar", "options", "pool", "request",
           "results", "series"]
