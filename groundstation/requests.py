"""What the ground station answers on its queryables: `swarm fault ...` (validated and applied by its
fault control) and the vehicles' id claims (groundstation.claims). A malformed request is counted and
answered with the error, never fatal."""

from __future__ import annotations

from bus.claims import ClaimReply, ClaimRequest
from bus.errors import DecodeError
from bus.keys import KeySpace
from bus.plan import FaultReply, FaultRequest, decode_json, encode_json
from bus.rejections import Rejections
from bus.session import Request
from groundstation.claims import IdRegister
from groundstation.fault_control import FaultControl
from groundstation.rundir import RunDirectory


class Requests:
    def __init__(
        self, keys: KeySpace, faults: FaultControl, ids: IdRegister, rejections: Rejections, run: RunDirectory
    ) -> None:
        self.keys, self.faults, self.ids, self.rejections, self.run = keys, faults, ids, rejections, run

    def answer(self, request: Request, *, now_us: int, alive: set[int]) -> bool:
        """Answer ``request`` at sim time ``now_us`` (``alive``: the vehicles on the bus); True when
        the fault plan changed (it must go out)."""
        if request.key == self.keys.claim():
            try:
                reply = self.ids.claim(decode_json(ClaimRequest, request.payload), alive=alive)
            except DecodeError as exc:
                self.rejections.reject("malformed", request.key, str(exc))
                reply = ClaimReply(ok=False, error=str(exc))
            request.respond(encode_json(reply))
            if reply.ok:
                self.run.event("vehicle_claimed", now_us, vehicle=reply.vehicle_id, restarts=reply.restarts)
            return False
        try:
            fault_reply = self.faults.request(decode_json(FaultRequest, request.payload))
        except DecodeError as exc:
            self.rejections.reject("malformed", request.key, str(exc))
            fault_reply = FaultReply(ok=False, error=str(exc), plan=self.faults.plan())
        request.respond(encode_json(fault_reply))
        return fault_reply.ok
