"""Which transport carries user data: the RTPS submessages a ping-pong sends over loopback UDP.

Run by ``test_dds_profile.py`` as ``python user_data_over_udp.py ROUND_TRIPS`` as root of a network namespace of
its own (``unshare --map-root-user --net``), so that a packet socket may read ``lo`` and no other process's
traffic is on it. It counts, in every UDP datagram sent on ``lo`` while a Reference ping-pong of ROUND_TRIPS
round trips runs between two processes, the DATA and DATA_FRAG submessages of user-defined writers (RTPS entity
kinds 0x00-0x3f; the builtin discovery writers are 0xc0-0xff). Heartbeats, acknowledgements and discovery are
not counted, so the figure does not grow with wall time or load: it is 0 when user data goes over shared memory
and about two a round trip when it goes over UDP. Prints one JSON line: ``user_data_submessages``,
``rtps_datagrams`` (every RTPS datagram seen) and ``dropped`` (datagrams the kernel could not queue for us).
"""
from __future__ import annotations

import json
import socket
import struct
import sys
import tempfile
import threading
from pathlib import Path

ETH_P_ALL = 0x0003
ETH_P_IP = 0x0800
#: getsockopt(SOL_PACKET, PACKET_STATISTICS): struct tpacket_stats {tp_packets, tp_drops}.
SOL_PACKET, PACKET_STATISTICS = 263, 6
RTPS_HEADER_BYTES = 20
DATA, DATA_FRAG = 0x15, 0x16
#: Submessages whose length may be 0 with more submessages after them (elsewhere 0 means "to the end").
PAD, INFO_TS = 0x01, 0x09
#: Offset of the writer's entity kind in a DATA / DATA_FRAG body (extraFlags 2, octetsToInlineQos 2, readerId 4,
#: writerId's key 3).
WRITER_KIND_OFFSET = 11
BUILTIN_KIND_BITS = 0xC0


def udp_payload(frame: bytes) -> bytes | None:
    """The UDP payload of an Ethernet frame of ``lo`` (None for anything else or an IP fragment past the first)."""
    if len(frame) < 14 or struct.unpack_from("!H", frame, 12)[0] != ETH_P_IP:
        return None
    ip = frame[14:]
    header_bytes, protocol, fragment = (ip[0] & 0x0F) * 4, ip[9], struct.unpack_from("!H", ip, 6)[0] & 0x1FFF
    if protocol != socket.IPPROTO_UDP or fragment:
        return None
    return ip[header_bytes + 8:]


def user_data_submessages(datagram: bytes) -> int:
    """The DATA and DATA_FRAG submessages of user-defined writers in one RTPS datagram."""
    count, at = 0, RTPS_HEADER_BYTES
    while at + 4 <= len(datagram):
        kind, flags = datagram[at], datagram[at + 1]
        length = struct.unpack_from("<H" if flags & 1 else ">H", datagram, at + 2)[0]
        body = datagram[at + 4:]
        if kind in (DATA, DATA_FRAG) and len(body) > WRITER_KIND_OFFSET:
            count += (body[WRITER_KIND_OFFSET] & BUILTIN_KIND_BITS) == 0
        if length == 0 and kind not in (PAD, INFO_TS):  # the last submessage runs to the end of the datagram
            break
        at += 4 + length
    return count


def capture_while(work: threading.Thread) -> dict[str, int]:
    """Read every datagram sent on ``lo`` until ``work`` (started here) has ended, and count them."""
    sniffer = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    sniffer.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 24)  # as much as net.core.rmem_max allows
    sniffer.bind(("lo", 0))
    sniffer.settimeout(0.2)
    counts = {"user_data_submessages": 0, "rtps_datagrams": 0}
    work.start()
    while work.is_alive():
        try:
            frame, address = sniffer.recvfrom(65536)
        except TimeoutError:
            continue
        payload = udp_payload(frame) if address[2] == socket.PACKET_OUTGOING else None
        if payload is not None and payload.startswith(b"RTPS"):
            counts["rtps_datagrams"] += 1
            counts["user_data_submessages"] += user_data_submessages(payload)
    counts["dropped"] = struct.unpack("II", sniffer.getsockopt(SOL_PACKET, PACKET_STATISTICS, 8))[1]
    return counts


def main(round_trips_n: int) -> None:
    from cnc_tools.bench.peers import round_trips

    errors: list[BaseException] = []

    def ping_pong() -> None:
        try:
            round_trips(Path(tempfile.mkdtemp()), "reference", round_trips_n, 10)
        except BaseException as err:  # handed to the main thread, which raises it
            errors.append(err)

    counts = capture_while(threading.Thread(target=ping_pong))
    if errors:
        raise errors[0]
    print(json.dumps(counts))


if __name__ == "__main__":
    main(int(sys.argv[1]))
