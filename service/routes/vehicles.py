"""``PUT`` and ``GET /v1/vehicles/{vehicle_id}``: a vehicle's switch and category (5.2), and its state."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path

from ..answer_schemas import VehicleState
from ..decoding import DecodedSwitch, decode
from ..deps import AdminDep, BodyDep, CallerDep, RegistryDep, ServiceDep, WorkDep
from ..keys import vehicle_key
from ..networks import ServedNetwork
from ..schemas import SWITCH_ADAPTER, VEHICLE_ID_PATTERN, Message, VehicleSwitch
from ..vehicles import LoadedVehicles
from .common import BOUNDED, INVALID_BODY, KEYED, STORE, json_body

__all__ = ["router", "vehicle_state"]

router = APIRouter(tags=["vehicles"])

#: The path parameter naming a vehicle (within the caller's fleet).
VehicleId = Annotated[
    str, Path(min_length=1, max_length=128, pattern=VEHICLE_ID_PATTERN, description="the vehicle: no '/', no U+0000")
]


def vehicle_state(vehicles: LoadedVehicles, networks: list[ServedNetwork], key: str, vehicle_id: str) -> dict[str, Any]:
    """The contract's VehicleState of the vehicle kept as ``key``, which its fleet calls ``vehicle_id``."""
    status = vehicles.status(key)
    session = vehicles.session(key)
    return {
        "vehicle_id": vehicle_id,
        "switched_on": status.switched_on,
        "category": vehicles.category(key),
        "state": status.state.value,
        "fault": status.fault.value if status.fault is not None else None,
        "fault_code": status.fault.code if status.fault is not None else None,
        "activated": status.activated,
        "last_timestamp_s": status.last_timestamp_s,
        "network": networks[session.network_index].name if session and session.lane_id else None,
        "lane_id": session.lane_id if session else None,
    }


@router.put(
    "/v1/vehicles/{vehicle_id}",
    response_model=VehicleState,
    summary="Switch CSWS on or off for a vehicle (5.2) and set its category",
    responses={
        403: {"model": Message, "description": "the key's role may not switch vehicles"},
        **INVALID_BODY,
        **STORE,
        **KEYED,
        **BOUNDED,
    },
    openapi_extra=json_body(VehicleSwitch),
)
async def put_vehicle(
    principal: AdminDep,
    vehicle_id: VehicleId,
    body: BodyDep,
    service: ServiceDep,
    registry: RegistryDep,
    work: WorkDep,
) -> dict[str, Any]:
    """Switch a vehicle of the caller's fleet on or off and set its category; its state after."""
    setting = decode(body, DecodedSwitch, SWITCH_ADAPTER)
    key = vehicle_key(principal.fleet, vehicle_id)

    def configure(vehicles: LoadedVehicles, _vehicle_ids: Any) -> dict[str, Any]:
        vehicles.configure(key, setting.switched_on, setting.category)
        return vehicle_state(vehicles, service.networks, key, vehicle_id)

    state: dict[str, Any] = await work.run(registry.transact, {key}, configure)
    return state


@router.get(
    "/v1/vehicles/{vehicle_id}",
    response_model=VehicleState,
    summary="A vehicle's switch, category and system state",
    responses={404: {"model": Message, "description": "a vehicle never queried or set, or expired"}, **STORE, **KEYED},
)
async def get_vehicle(
    principal: CallerDep, vehicle_id: VehicleId, service: ServiceDep, registry: RegistryDep, work: WorkDep
) -> dict[str, Any]:
    """The state of a vehicle of the caller's fleet; 404 for one it never queried or set."""
    key = vehicle_key(principal.fleet, vehicle_id)

    def state() -> dict[str, Any]:
        with registry.read({key}) as vehicles:
            if not vehicles.known(key):
                raise HTTPException(
                    404, f"unknown vehicle {vehicle_id!r}: never queried or set, or its session expired"
                )
            return vehicle_state(vehicles, service.networks, key, vehicle_id)

    found: dict[str, Any] = await work.run(state)
    return found
