"""Cross-check of our Dynamixel packets against ROBOTIS' own Python SDK (PyPI dynamixel-sdk).

Reads JSON cases on stdin, writes JSON results on stdout. Each case is
  {"proto": 1|2, "op": ..., "args": {...}, "ours": "<hex of the bytes our Rust code built>"}
Instruction ops (ping, read, write, sync_write, sync_read) are built by the SDK's own
packet handler methods through a fake port that records what they write: the result
"sdk" is those bytes, to be compared with ours. Status ops are built with the SDK's
txPacket (its stuffing, CRC or checksum), and our bytes are parsed by the SDK's rxPacket:
"parsed" is what the SDK read from ours (result code, id, error, params).
"""
import json
import sys

import dynamixel_sdk as sdk
from dynamixel_sdk.robotis_def import COMM_SUCCESS


class FakePort:
    """The little of PortHandler the packet handlers use: records writes, serves reads."""

    def __init__(self, rx=b""):
        self.is_using = False
        self.written = bytearray()
        self.rx = bytearray(rx)

    def clearPort(self):
        pass

    def writePort(self, packet):
        self.written.extend(packet)
        return len(packet)

    def readPort(self, length):
        out = list(self.rx[:length])
        del self.rx[:length]
        return out

    def isPacketTimeout(self):
        return len(self.rx) == 0

    def setPacketTimeout(self, packet_length):
        pass

    def setPacketTimeoutMillis(self, msec):
        pass


def handler(proto):
    return sdk.PacketHandler(1.0 if proto == 1 else 2.0)


def build_instruction(proto, op, a):
    ph = handler(proto)
    port = FakePort()
    if op == "ping":
        ph.ping(port, a["id"])
    elif op == "read":
        ph.readTx(port, a["id"], a["address"], a["length"])
    elif op == "write":
        ph.writeTxOnly(port, a["id"], a["address"], len(a["data"]), list(a["data"]))
    elif op == "sync_write":
        # Through the SDK's GroupSyncWrite, as a user of the SDK would.
        group = sdk.GroupSyncWrite(port, ph, a["address"], a["length"])
        for sid, data in a["values"]:
            assert group.addParam(sid, list(data))
        group.txPacket()
    elif op == "sync_read":
        group = sdk.GroupSyncRead(port, ph, a["address"], a["length"])
        for sid in a["ids"]:
            assert group.addParam(sid)
        group.txPacket()
    else:
        raise ValueError(op)
    return bytes(port.written)


def build_status(proto, a):
    """A status packet made by the SDK's own txPacket (stuffing, CRC / checksum)."""
    ph = handler(proto)
    port = FakePort()
    params = list(a["params"])
    if proto == 2:
        pkt = [0] * (11 + len(params) + 8)  # room for stuffing
        pkt[4] = a["id"]
        n = len(params) + 4
        pkt[5], pkt[6] = n & 0xFF, n >> 8
        pkt[7] = 0x55
        pkt[8] = a["error"]
        pkt[9:9 + len(params)] = params
        pkt = pkt[: 7 + n]
        # The SDK's own stuffing. (txPacket calls addStuffing too but, in SDK 4.1.0, drops
        # its result when the packet grows: a stuffed packet is only made this way.)
        pkt = ph.addStuffing(pkt)
    else:
        n = len(params) + 2
        pkt = [0xFF, 0xFF, a["id"], n, a["error"]] + params + [0]
    assert ph.txPacket(port, pkt) == COMM_SUCCESS
    return bytes(port.written)


def parse_status(proto, ours):
    ph = handler(proto)
    port = FakePort(ours)
    if proto == 2:
        pkt, result = ph.rxPacket(port, False)
        if result != COMM_SUCCESS:
            return {"result": result}
        n = pkt[5] | (pkt[6] << 8)
        return {"result": result, "id": pkt[4], "error": pkt[8], "params": list(pkt[9: 7 + n - 2])}
    pkt, result = ph.rxPacket(port)
    if result != COMM_SUCCESS:
        return {"result": result}
    n = pkt[3]
    return {"result": result, "id": pkt[2], "error": pkt[4], "params": list(pkt[5: 3 + n])}


def main():
    cases = json.load(sys.stdin)
    out = []
    for c in cases:
        ours = bytes.fromhex(c["ours"])
        if c["op"] == "status":
            out.append({
                "sdk": build_status(c["proto"], c["args"]).hex(),
                "parsed": parse_status(c["proto"], ours),
            })
        else:
            out.append({"sdk": build_instruction(c["proto"], c["op"], c["args"]).hex()})
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
