"""What the tasks on files return: frozen records with the fields the CLI, the chain and its report read.

- :class:`CorrectionResult`: :func:`brdfcorr.tasks.correct.correct_files` (``brdfcorr correct``, a
  chain's correct step);
- :class:`TopographicSummary`: the topographic step of a correction on tilted surfaces;
- :class:`NbarResult`: :func:`brdfcorr.tasks.nbar.nbar_files` (``brdfcorr nbar``).

The fit and assessment tasks return their own records (:class:`brdfcorr.tasks.fit.ImageryFitResult`,
:class:`brdfcorr.tasks.goniometer.MeasurementFit`, :class:`brdfcorr.tasks.assess.Assessment`), whose
``report()`` is what a chain's report holds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from brdfcorr.params import ReferenceGeometry

if TYPE_CHECKING:  # the sensor readers load only where a product is read
    from brdfcorr.io.sensors.folders import ProductFolder
    from brdfcorr.io.sensors.hls import HlsGranule

__all__ = ["CorrectionResult", "TopographicSummary", "NbarResult"]


@dataclass(frozen=True)
class TopographicSummary:
    """The topographic (illumination) step of a correction (:class:`brdfcorr.tasks.correct.Terrain`).

    Attributes
    ----------
    method : str
        ``"cosine"``, ``"c"``, ``"scs"`` or ``"scs+c"``
        (:func:`brdfcorr.correction.topographic.topographic_correction`).
    c : tuple of dict
        The C fit per class and band, one record a row (``class_id``, ``band``, ``c`` [1],
        ``accepted``, ...), empty for the methods without C.
    """

    method: str
    c: tuple[Mapping[str, object], ...] = ()

    @property
    def rejected(self) -> int:
        """The number of class-band C fits rejected (those pixels flagged, not corrected by C)."""
        return sum(not row["accepted"] for row in self.c)

    def as_dict(self) -> dict[str, object]:
        """``{"method": ..., "c": [...]}``, as a chain's run report holds it."""
        return {"method": self.method, "c": [dict(row) for row in self.c]}


@dataclass(frozen=True)
class CorrectionResult:
    """What one correction of an image file did (:func:`brdfcorr.tasks.correct.correct_files`).

    Attributes
    ----------
    counts : mapping of str to int
        Pixel counts [pixels] of the QA outcomes (:func:`brdfcorr.correction.qa_counts`:
        ``corrected``, ``limited``, ``unknown_class``, ``no_class``, ``nodata``) and, with an integer
        output (``outputs.data_type="input"``), ``out_of_range``: the valid pixels stored as nodata
        and flagged ``nodata`` since some band did not fit the type (counted among ``nodata``).
    reference : ReferenceGeometry
        The reference geometry used (a ``"mean"`` sun zenith replaced by the scene's mean [deg]).
    notes : tuple of str
        One line each, what the user should know (most valid pixels left uncorrected,
        :func:`brdfcorr.tasks.correct.uncorrected_note`; classes without errors in an uncertainty
        output); each also a warning.
    topographic : TopographicSummary, optional
        The topographic step, with terrain (None without).
    """

    counts: Mapping[str, int]
    reference: ReferenceGeometry
    notes: tuple[str, ...] = ()
    topographic: TopographicSummary | None = None


@dataclass(frozen=True)
class NbarResult:
    """What one NBAR run did (:func:`brdfcorr.tasks.nbar.nbar_files`).

    Attributes
    ----------
    counts : mapping of str to int
        Pixel counts [pixels] of the QA outcomes of the written output
        (:func:`brdfcorr.correction.qa_counts`).
    reference : ReferenceGeometry
        The reference geometry used.
    product : ProductFolder or HlsGranule
        The product read (:func:`brdfcorr.io.sensors.folders.find_product`,
        :func:`brdfcorr.io.sensors.hls.find_hls_granule`): its ``bands``, ``resolution`` [m], files.
    """

    counts: Mapping[str, int]
    reference: ReferenceGeometry
    product: ProductFolder | HlsGranule
