"""The bridge's lifecycle over its standard services (change_state, get_state), for
CncClient: a cell controller takes a machine down (a controlled stop) and up again."""
from __future__ import annotations

import time
from typing import Any, Callable

RESEND_QUESTION_S = 1.0  # a question unanswered this long is asked again (see BridgeLifecycle._call)


class CncClientError(RuntimeError):
    """The planner or bridge could not be reached, or the bridge refused a transition."""


class BridgeLifecycle:
    """The lifecycle services of the bridge node at ``path`` (``<namespace>/cnc_servo_bridge``),
    called through ``node``, which ``spin_once(timeout_s)`` spins while an answer is awaited."""

    def __init__(self, node: Any, path: str, spin_once: Callable[[float], None]) -> None:
        self.node, self.path, self.spin_once = node, path, spin_once
        self._clients: dict[str, Any] = {}  # service clients, made when first used

    def transition(self, label: str, timeout: float) -> str:
        """Ask for the transition ``label``; the state the bridge is in afterwards.

        Raises:
            CncClientError: no answer within ``timeout`` s, or the bridge refused.
        """
        from lifecycle_msgs.srv import ChangeState

        request = ChangeState.Request()
        request.transition.label = label
        if not self._call(ChangeState, "change_state", request, timeout).success:
            raise CncClientError(f"the bridge refused '{label}' (it is {self.state(timeout)})")
        return self.state(timeout)

    def state(self, timeout: float) -> str:
        """The bridge's lifecycle state: unconfigured, inactive, active or finalized.

        Raises:
            CncClientError: no answer within ``timeout`` s.
        """
        from lifecycle_msgs.srv import GetState

        return self._call(GetState, "get_state", GetState.Request(), timeout, resend=True).current_state.label

    def _call(self, service_type: Any, service: str, request: Any, timeout: float, resend: bool = False) -> Any:
        """``resend`` a question each RESEND_QUESTION_S unanswered: Fast DDS drops a response
        to a reader not yet matched (only for questions that change nothing)."""
        name = f"{self.path}/{service}"
        if (client := self._clients.get(name)) is None:
            client = self._clients[name] = self.node.create_client(service_type, name)
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                raise CncClientError(f"no bridge answers on {name} (waited {timeout:g} s)")
            self.spin_once(0.05)
        future, sent = client.call_async(request), time.monotonic()
        while not future.done():
            if time.monotonic() > deadline:
                raise CncClientError(f"no answer on {name} within {timeout:g} s")
            if resend and time.monotonic() - sent > RESEND_QUESTION_S:
                future, sent = client.call_async(request), time.monotonic()
            self.spin_once(0.05)
        return future.result()
