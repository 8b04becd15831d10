"""The time limits of reaching a dask.distributed cluster (issue 26, item 12) are the ones
docs/scaling.md states: 10 s to hear the scheduler, 60 s for a first worker."""

import re
from pathlib import Path

import pytest

from brdfcorr.errors import InputError
from brdfcorr.io import cluster

SCALING = Path(__file__).resolve().parents[2] / "docs" / "scaling.md"


def _cluster_section() -> str:
    text = SCALING.read_text()
    return text[text.index("## Run one scene on a dask.distributed cluster"):text.index("## Chains on a cluster")]


def test_the_documented_limits_are_the_code_s():
    section = _cluster_section()
    stated = [float(value) for value in re.findall(r"\*\*(\d+) s\*\*", section)]
    # The first limit is the connect and handshake of the scheduler, the second the first worker.
    assert stated == [cluster.CONNECT_TIMEOUT, cluster.WORKER_TIMEOUT] == [10.0, 60.0]
    # the CLI and chains both connect with brdfcorr.io.cluster.connect_cluster and these defaults
    for setting in ("--scheduler", "DASK_SCHEDULER_ADDRESS", "engine.address"):
        assert setting in section


def test_the_documented_message_of_a_bad_address_is_the_code_s():
    with pytest.raises(InputError) as caught:
        cluster.scheduler_identity("notanaddress", 1.0, "--scheduler")
    message = str(caught.value)
    assert message.startswith("--scheduler: 'notanaddress' is no dask scheduler address (")
    assert message.endswith("; expected e.g. tcp://host:8786")
    for fragment in ("is no dask scheduler address", "expected e.g. tcp://host:8786"):
        assert fragment in _cluster_section()
