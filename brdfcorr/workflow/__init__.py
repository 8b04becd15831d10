"""Whole tasks on files, shared by the CLI and chains.

- :mod:`~brdfcorr.workflow.tasks`: correct an image file, fit a goniometer table, fit classes from
  scenes (one library function per task);
- :mod:`~brdfcorr.workflow.classmaps`: NDVI strata and land-cover maps as class-map files;
- :mod:`~brdfcorr.workflow.config`, :mod:`~brdfcorr.workflow.patterns`: chain configs and their
  per-scene name patterns;
- :mod:`~brdfcorr.workflow.plan`, :mod:`~brdfcorr.workflow.chain`,
  :mod:`~brdfcorr.workflow.report`: plan, run and report a chain;
- :mod:`~brdfcorr.workflow.demo`: the demo scene and its run.
"""

#: The task modules, imported at first use as ``brdfcorr.workflow.<name>`` (importing this package
#: loads none of them: the command line pays only for the task it runs).
__all__ = ["api", "assessment", "chain", "classmaps", "config", "correction", "demo", "nbar", "patterns", "plan",
           "report", "request", "tasks"]
