"""MAVLink FTP (FILE_TRANSFER_PROTOCOL): the simulator keeps no files, so every request is
refused at once with a NAK instead of left to time out.

Ground stations try FTP first for parameters and missions (MAVProxy waits seconds for an
answer before falling back to PARAM_REQUEST_LIST); a prompt NAK makes them fall back at once.
AUTOPILOT_VERSION does not claim MAV_PROTOCOL_CAPABILITY_FTP.
"""

from __future__ import annotations

import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink

_HEADER = struct.Struct("<HBBBBBBI")  # seq, session, opcode, size, req_opcode, burst, pad, offset
_PAYLOAD = 251
OP_TERMINATE_SESSION = 1
OP_RESET_SESSIONS = 2
OP_ACK = 128
OP_NAK = 129
ERR_UNKNOWN_COMMAND = 7


def reply(msg) -> object | None:
    """The answer to a FILE_TRANSFER_PROTOCOL request: an ACK for closing sessions, a NAK
    (unknown command) for anything else; None when the payload is too short to be one."""
    payload = bytes(msg.payload)
    if len(payload) < _HEADER.size:
        return None
    seq, session, opcode, *_ = _HEADER.unpack_from(payload)
    if opcode in (OP_ACK, OP_NAK):
        return None  # a reply, not a request
    if opcode in (OP_TERMINATE_SESSION, OP_RESET_SESSIONS):
        body = _HEADER.pack((seq + 1) & 0xFFFF, session, OP_ACK, 0, opcode, 0, 0, 0)
    else:
        body = _HEADER.pack((seq + 1) & 0xFFFF, session, OP_NAK, 1, opcode, 0, 0, 0)
        body += bytes([ERR_UNKNOWN_COMMAND])
    data = list(body.ljust(_PAYLOAD, b"\0"))
    return mavlink.MAVLink_file_transfer_protocol_message(
        0, msg.get_srcSystem(), msg.get_srcComponent(), data
    )
