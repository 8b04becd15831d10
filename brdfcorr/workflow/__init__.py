"""Whole tasks on files: chain configs (:mod:`~brdfcorr.workflow.config`), chain runs
(:mod:`~brdfcorr.workflow.chain`), the file-level correction and fits that the CLI and chains share
(:mod:`~brdfcorr.workflow.tasks`), and the demo (:mod:`~brdfcorr.workflow.demo`)."""
