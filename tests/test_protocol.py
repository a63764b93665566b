"""The framed protocol: codec, payloads, and a decoder that survives any stream."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactilize.actuators import frames as P
from tactilize.actuators.frames import _framing


def test_crc_matches_published_check_value():
    # CRC-16/CCITT-FALSE check value from the CRC catalogue.
    assert P.crc16_ccitt(b"123456789") == 0x29B1
    assert P.crc16_ccitt(b"") == 0xFFFF


def test_frame_layout():
    frame = P.encode_frame(7, P.Command.HEARTBEAT)
    assert frame[0] == P.START
    assert frame[1] == 0  # payload length
    assert frame[2] == 7
    assert frame[3] == P.Command.HEARTBEAT
    assert int.from_bytes(frame[4:6], "big") == P.crc16_ccitt(frame[1:4])
    assert len(P.encode_frame(300, 1, b"abc")) == P.OVERHEAD + 3
    assert P.encode_frame(300, 1)[2] == 300 % 256


def test_encode_rejects_oversized_payload():
    with pytest.raises(ValueError):
        P.encode_frame(0, 1, bytes(P.MAX_PAYLOAD + 1))


def test_set_channel_round_trip_in_si_units():
    payload = P.encode_set_channel(1, 123.456, 400e-6, 0.5)
    sc = P.decode_set_channel(payload)
    assert sc.channel == 1
    assert sc.frequency_mhz == 123456
    assert sc.pulse_width_ns == 400_000
    assert sc.frequency_hz == pytest.approx(123.456)
    assert sc.pulse_width_s == pytest.approx(400e-6)
    assert sc.amplitude == pytest.approx(0.5, abs=1 / 65535)
    with pytest.raises(ValueError):
        P.encode_set_channel(0, 100, 1e-3, 1.5)


def test_status_round_trip():
    status = P.ControllerStatus(
        version=1,
        watchdog_tripped=True,
        uptime_s=12.345,
        frames_ok=10,
        frames_bad=2,
        channels=(P.ChannelStatus(True, 120.0, 4e-4, 1.0), P.ChannelStatus(False, 0.0, 0.0, 0.0)),
        min_frequency_hz=1.0,
        max_frequency_hz=300.0,
        min_pulse_width_s=1e-5,
        max_pulse_width_s=5e-3,
        max_duty_ratio=0.2,
        watchdog_s=0.2,
    )
    payload = P.encode_status(status)
    assert len(payload) == struct.calcsize(P.STATUS_FORMAT) <= P.MAX_PAYLOAD
    assert P.decode_status(payload) == status


def test_nak_decoding_names_reason_and_detail():
    assert P.decode_nak(bytes((2, 3))) == (P.NakReason.REFUSED_LIMIT, P.Refused.DUTY)
    assert P.decode_nak(bytes((99, 77))) == (99, 77)


def test_decoder_finds_frames_split_byte_by_byte():
    frames = [P.encode_frame(i, P.Command.SET, P.encode_set_channel(0, 100 + i, 3e-4, 1.0)) for i in range(5)]
    dec = P.FrameDecoder()
    got = []
    for byte in b"".join(frames):
        got += dec.feed(bytes((byte,)))
    assert [f.seq for f in got] == list(range(5))
    assert len(dec) == 0


def test_decoder_resyncs_after_corrupt_header_that_swallows_a_frame():
    good = P.encode_frame(9, P.Command.HEARTBEAT)
    # A start byte followed by a plausible length: the decoder first takes the
    # good frame as that candidate's payload, fails the CRC, and must rescan.
    corrupt = bytes((P.START, 10, 1, 1))
    dec = P.FrameDecoder()
    got = dec.feed(corrupt + good + bytes(12))
    assert got == [P.Frame(9, P.Command.HEARTBEAT, b"")]
    assert dec.crc_errors == 1


def test_decoder_rejects_bad_checksum():
    frame = bytearray(P.encode_frame(1, P.Command.STOP))
    frame[-1] ^= 0x01
    dec = P.FrameDecoder()
    assert dec.feed(bytes(frame)) == []
    assert dec.crc_errors == 1


def test_expire_releases_frames_held_by_a_stale_length():
    dec = P.FrameDecoder()
    assert dec.feed(bytes((P.START, 60, 0, 0))) == []  # waits for 60 payload bytes
    good = P.encode_frame(5, P.Command.STATUS)
    assert dec.feed(good) == []  # held back behind the stale candidate
    assert dec.expire() == [P.Frame(5, P.Command.STATUS, b"")]
    assert len(dec) == 0
    assert dec.expire() == []


def _drain(dec: P.FrameDecoder) -> list[P.Frame]:
    """Expire until nothing is held back (what a receiver does over a silence)."""
    out: list[P.Frame] = []
    while len(dec):
        out += dec.expire()
    return out


frames_st = st.lists(
    st.tuples(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=P.MAX_PAYLOAD)), min_size=1, max_size=6
)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400), st.lists(st.integers(1, 50), max_size=20))
def test_garbage_never_crashes_and_state_stays_bounded(garbage, cuts):
    dec = P.FrameDecoder()
    pos = 0
    for cut in cuts + [len(garbage)]:
        for f in dec.feed(garbage[pos : pos + cut]):
            # anything returned must be a real, checksum-valid frame
            assert P.encode_frame(f.seq, f.command, f.payload) in garbage
        pos += cut
    # a partial frame never holds more than one maximal frame's worth of bytes
    assert len(dec) < P.OVERHEAD + P.MAX_PAYLOAD


@settings(max_examples=300, deadline=None)
@given(frames_st, st.binary(max_size=100), st.lists(st.integers(1, 40), max_size=30))
def test_valid_frames_always_found_after_garbage(frames, garbage, cuts):
    stream = b"".join(P.encode_frame(s, c, p) for s, c, p in frames)
    dec = P.FrameDecoder()
    # Leading garbage may contain a start byte with a long length that holds
    # the first frames hostage until expiry, exactly as on the wire; a silence
    # (expire) then frees them.
    got = dec.feed(garbage)
    data = stream
    pos = 0
    for cut in cuts + [len(data)]:
        got += dec.feed(data[pos : pos + cut])
        pos += cut
    got += _drain(dec)
    want = [P.Frame(s & 0xFF, c, bytes(p)) for s, c, p in frames]
    # every sent frame is found, in order (garbage can only add frames, never lose ours)
    it = iter(got)
    assert all(any(g == w for g in it) for w in want)


@settings(max_examples=200, deadline=None)
@given(frames_st, st.integers(0, 10_000))
def test_a_flipped_bit_loses_at_most_the_frame_it_hit(frames, where):
    stream = bytearray(b"".join(P.encode_frame(s, c, p) for s, c, p in frames))
    bit = where % (len(stream) * 8)
    stream[bit // 8] ^= 1 << (bit % 8)
    dec = P.FrameDecoder()
    got = dec.feed(bytes(stream)) + _drain(dec)
    want = [P.Frame(s & 0xFF, c, bytes(p)) for s, c, p in frames]
    matched = sum(1 for w in want if w in got)
    assert matched >= len(want) - 1


def test_expire_stale_measures_the_candidate_not_the_last_byte(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(_framing.time, "monotonic", lambda: clock[0])
    dec = P.FrameDecoder()
    dec.feed(bytes((P.START, 64, 0, 0)))
    got = []
    for _ in range(3):  # bytes keep arriving every 30 ms behind the stale candidate
        clock[0] += 0.03
        got += dec.feed(P.encode_frame(1, P.Command.ACK, b"\x03\x00"))
        got += dec.expire_stale(0.05)
    # the candidate expired 60 ms after it started, although bytes came every 30 ms
    assert got.count(P.Frame(1, P.Command.ACK, b"\x03\x00")) == 3
    assert len(dec) == 0 and dec.pending_since_s is None
