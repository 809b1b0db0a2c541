"""The library's exception family: one base class for every error csws raises on purpose.

Each specific error keeps its standard base as well (``ValueError`` for bad input,
``RuntimeError`` for an outside program that failed), so ``except ValueError`` and
``except RuntimeError`` keep catching them, while ``except CswsError`` catches all of them.
"""

from __future__ import annotations

__all__ = ["CswsError"]


class CswsError(Exception):
    """The base of every error the library raises for bad input or a failed outside program.

    Subclasses also derive from the standard exception that describes them:

    * ``ValueError`` for input the library cannot use: :class:`csws.road.network.NetworkError`,
      :class:`csws.osm.importer.OsmImportError`, :class:`csws.sweep.study.StudyError`;
    * ``RuntimeError`` for an outside program or service that is missing or failed:
      :class:`csws.sumo.binaries.SumoNotFoundError`, :class:`csws.sumo.netbuild.NetconvertError`,
      :class:`csws.cosim.sumo.SumoStopped`, :class:`csws.cosim.evaluators.ServiceError`.

    Notes
    -----
    Catch ``CswsError`` to handle any failure csws reports itself, and let other exceptions
    (programming errors) propagate.
    """
