"""``python -m brdfcorr``: the ``brdfcorr`` command, where its script is not on the PATH (a job
script that names the interpreter, an environment that was not activated)."""

from brdfcorr.cli import main

if __name__ == "__main__":
    main(prog_name="brdfcorr")
