"""One visit, several protocols: g, h, alpha, then the assessment, in one sitting.

:class:`Visit` offers the same methods as :class:`~.flow.Flow`, so the routes of
:mod:`.web` serve it unchanged.  Each protocol keeps its own session (its own
Latin-square row, plan and protocol version); the visit only chains them:

- registration happens in the first protocol; when a session is done, the
  participant's session in the next protocol is created under the same ID,
  with the screen calibration copied (one calibration per visit: the screen
  and the pen have not changed);
- every request is routed by its session token to the protocol it belongs to,
  so a reload or a restarted server lands where the stored data say;
- images are addressed per protocol (``images/ID.png?protocol=NAME``), since
  two protocols may use the same image id for different pictures.
"""

from __future__ import annotations

from typing import Any

from ..actuators.base import Output
from .flow import Flow, FlowError
from .strokes import StrokeHandler

__all__ = ["Visit"]


class Visit:
    """Several protocols run in sequence by the same participants.

    Parameters
    ----------
    flows : list of Flow
        One per protocol, in the order a participant takes them; all on the same store.
    """

    def __init__(self, flows: list[Flow]):
        if not flows:
            raise ValueError("a visit needs at least one protocol")
        self.flows = list(flows)
        self.store = flows[0].store
        self.admin_token = flows[0].admin_token
        self.design = flows[0].design  # the welcome page's title and consent
        self.protocol_names = [f.design.name for f in flows]

    # ------------------------------------------------------------ routing

    def _flow_of(self, token: Any) -> int:
        sess = self.store.session_by_token(token) if isinstance(token, str) and len(token) < 100 else None
        if sess is not None:
            for i, f in enumerate(self.flows):
                if f.design_version.id == sess.design_version_id:
                    return i
        raise FlowError("session", "unknown session; start again or resume with your participant ID", 404)

    def _decorate(self, i: int, state: dict) -> dict:
        state["visit"] = {"part": i + 1, "parts": len(self.flows), "protocols": self.protocol_names}
        if state.get("state") == "trial":
            for im in state["trial"]["images"]:
                im["url"] = f"{im['url']}?protocol={self.flows[i].design.name}"
        return state

    def _advance(self, i: int, state: dict) -> dict:
        """The state to show: this protocol's, or the next protocol's once this one is done."""
        while state.get("state") == "done" and i + 1 < len(self.flows):
            code, calibration = state["participant"], state.get("calibration")
            nxt = self.flows[i + 1]
            sess = self.store.session_by_code(nxt.design.name, code)
            if sess is None:
                part = self.store.participant(self.flows[i].session_of(state["session"]))
                token = nxt.start(code, True, simulated=part.simulated)["session"]
            else:
                token = sess.token
            if calibration and nxt.session_of(token).calibrated_at is None:
                nxt.calibrate(token, {"mm_per_px": calibration["mm_per_px"], "felt": True})
            i, state = i + 1, nxt.state(token)
        return self._decorate(i, state)

    # ------------------------------------------------------------ the Flow interface

    def start(self, code: Any, consent: Any, **kw: Any) -> dict:
        return self._advance(0, self.flows[0].start(code, consent, **kw))

    def resume(self, code: Any) -> dict:
        state = self.flows[0].resume(code)
        return self._advance(0, state)

    def state(self, token: str) -> dict:
        i = self._flow_of(token)
        return self._advance(i, self.flows[i].state(token))

    def calibrate(self, token: str, data: Any) -> dict:
        i = self._flow_of(token)
        return self._advance(i, self.flows[i].calibrate(token, data))

    def end_break(self, token: str, trial_index: Any) -> dict:
        i = self._flow_of(token)
        return self._advance(i, self.flows[i].end_break(token, trial_index))

    def submit(self, token: str, *args: Any, **kw: Any) -> dict:
        i = self._flow_of(token)
        out = self.flows[i].submit(token, *args, **kw)
        recorded = out.get("recorded")
        out = self._advance(i, out)
        out["recorded"] = recorded
        return out

    def stroke_handler(self, token: str, output: Output | None = None) -> StrokeHandler:
        return self.flows[self._flow_of(token)].stroke_handler(token, output)

    def image_png(self, image_id: str, protocol: str | None = None) -> bytes:
        for f in self.flows:
            if protocol in (None, f.design.name):
                return f.image_png(image_id)
        raise FlowError("image", f"no protocol {protocol!r} in this visit", 404)
