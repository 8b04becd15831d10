"""The correction of reflectance to a reference sun/view geometry, one package whose modules
share their internals by design; its public face is below.

- :func:`normalize` (:mod:`.normalization`): the per-class BRDF normalization, lazy and chunked;
- :func:`normalize_at_nodes` (:mod:`.nodes`): one class, the factor at a coarse angle grid's nodes;
- :class:`QA` (:mod:`.qa`): the one set of QA flags every step writes, and :func:`qa_counts`;
- :func:`resolve_reference` (:mod:`.reference`): the reference geometry, resolved once;
- :mod:`.terrain`: slope and aspect, sun and view in a tilted surface's frame;
- :func:`topographic_correction` (:mod:`.topographic`): cosine, C, SCS, SCS+C;
- :func:`correction_uncertainty` (:mod:`.uncertainty`): the per-pixel 1-sigma of the correction.

Internals shared between them: :mod:`.inputs` (inputs checked and resolved to the bands once) and
:mod:`.blocks` (per-class plans, a block's pixel geometry).
"""

from brdfcorr.correction.nodes import normalize_at_nodes
from brdfcorr.correction.normalization import Normalized, normalize
from brdfcorr.correction.qa import QA, qa_attrs, qa_counts
from brdfcorr.correction.reference import describe_limits, resolve_reference
from brdfcorr.correction.topographic import Topographic, topographic_correction
from brdfcorr.correction.uncertainty import correction_uncertainty

__all__ = [
    "normalize",
    "normalize_at_nodes",
    "Normalized",
    "QA",
    "qa_attrs",
    "qa_counts",
    "resolve_reference",
    "describe_limits",
    "topographic_correction",
    "Topographic",
    "correction_uncertainty",
]
