"""Who may do what on the OPC UA server: operators and viewers (SPEC section 13).

An operator calls any method (StartJob, Hold, a job order's Store or Abort...); a viewer
reads, browses and subscribes to everything and calls only the methods that read
(:attr:`RoleRuleset.reading_methods`, e.g. a job order's RequestJobResponseByJobOrderID):
a call of any other method, by a viewer, is refused as a whole with BadUserAccessDenied
before it runs. Nobody writes a variable and nobody changes the address space.

Imports asyncua: import this module lazily (the server does, when it starts).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from asyncua import ua
from asyncua.crypto.permission_rules import USER_TYPES, PermissionRuleset

from cellrunner.plc.opcua_nodes import node_id

_log = logging.getLogger(__name__)

_IDS = ua.object_ids.ObjectIds
_WRITE = node_id(_IDS.WriteRequest_Encoding_DefaultBinary)
_CALL = node_id(_IDS.CallRequest_Encoding_DefaultBinary)
#: every request a logged-in user may send, writes excepted
_ALLOWED = frozenset(node_id(t) for t in USER_TYPES) - {_WRITE}


class RoleRuleset(PermissionRuleset):
    """asyncua's permission check by role: ``role_of(user name)`` is ``"operator"`` or
    ``"viewer"`` (the users file's, read when asked, so a changed role holds at once)."""

    def __init__(self, role_of: Callable[[str], str]) -> None:
        self.role_of = role_of
        #: the methods a viewer may call (they only read)
        self.reading_methods: set[Any] = set()

    def check_validity(self, user: Any, action_type_id: Any, body: Any) -> bool:
        if action_type_id not in _ALLOWED:
            return False
        if action_type_id != _CALL or self.role_of(getattr(user, "name", None) or "") != "viewer":
            return True
        try:
            from asyncua.ua.ua_binary import struct_from_binary

            params = struct_from_binary(ua.CallParameters, body.copy())
        except Exception:  # a malformed request: refused
            return False
        allowed = all(m.MethodId in self.reading_methods for m in params.MethodsToCall or [])
        if not allowed:
            _log.warning("OPC UA call refused: user %r is a viewer", user.name)
        return allowed
