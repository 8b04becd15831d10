"""Config-driven processing chains over many scenes, built on :mod:`brdfcorr.tasks`.

- :mod:`~brdfcorr.chain.config` (with ``config_inputs``, ``config_outputs``, ``config_steps``) and
  :mod:`~brdfcorr.chain.patterns`: chain configs and their per-scene name patterns;
- :mod:`~brdfcorr.chain.plan` (with :mod:`~brdfcorr.chain.scenes`, the scenes of a run, and
  :mod:`~brdfcorr.chain.resume`, fingerprints and what a resumed run skips),
  :mod:`~brdfcorr.chain.run` (with :mod:`~brdfcorr.chain.strata_step`, the class maps the strata
  step derives, :mod:`~brdfcorr.chain.products`, product folders' bands stacked for the run, and
  :mod:`~brdfcorr.chain.progress`, the scenes' progress), :mod:`~brdfcorr.chain.report`,
  :mod:`~brdfcorr.chain.quicklook`: plan, run and report a chain (:func:`~brdfcorr.chain.run.run_chain`,
  ``brdfcorr.run_chain``: a config file or a loaded config);
- :mod:`~brdfcorr.chain.demo`: the demo scene and its run.
"""

#: The chain modules, imported at first use as ``brdfcorr.chain.<name>``.
__all__ = ["config", "config_inputs", "config_outputs", "config_steps", "demo", "patterns", "plan", "products",
           "progress", "quicklook", "report", "resume", "run", "scenes", "strata_step"]
