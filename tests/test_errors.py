"""The library's errors are one family under CswsError and keep their standard bases."""

from __future__ import annotations

import pytest

from csws.cosim.evaluators import ServiceError
from csws.cosim.sumo import SumoStopped
from csws.errors import CswsError
from csws.osm.importer import OsmImportError
from csws.road.network import NetworkError
from csws.sumo.binaries import SumoNotFoundError
from csws.sumo.netbuild import NetconvertError
from csws.sweep.study import StudyError


@pytest.mark.parametrize(
    ("error", "standard_base"),
    [
        (NetworkError, ValueError),
        (OsmImportError, ValueError),
        (StudyError, ValueError),
        (SumoNotFoundError, RuntimeError),
        (NetconvertError, RuntimeError),
        (SumoStopped, RuntimeError),
        (ServiceError, RuntimeError),
    ],
)
def test_each_error_is_a_csws_error_and_keeps_its_standard_base(error: type[Exception], standard_base: type) -> None:
    raised = error("bad input")
    assert isinstance(raised, CswsError)
    assert isinstance(raised, standard_base)
    with pytest.raises(standard_base):
        raise raised
    with pytest.raises(CswsError):
        raise error("bad input")
