"""Reaching the pen page from a phone: the LAN address to bind and type, its QR code, and what works where.

A phone cannot reach a server on loopback, so ``tactilize serve --lan`` binds
this machine's address on the local network and prints the URL to type on the
phone, and the same URL as a QR code drawn in the terminal (by ``segno``).

Over plain HTTP from another machine the page is not a *secure context*
(docs/references.md, section 5 (secure contexts)): touch, pen and mouse input,
the drive and the phone's vibration work; the AudioWorklet output and Chromium's
``pointerrawupdate`` do not.  ``--https`` (see :mod:`.tls`) makes them work too.
"""

from __future__ import annotations

import io
import ipaddress
import socket
from typing import Iterable

from ..errors import TactilizeError

__all__ = ["lan_addresses", "choose_lan_address", "page_url", "qr_text", "context_notes"]

# Addresses on private networks, used only to ask the OS which local address its
# routing table would send from: connecting a UDP socket sends no packet.
_ROUTE_PROBES = ("10.255.255.255", "192.168.255.255", "172.31.255.255")


def lan_addresses() -> list[str]:
    """This machine's IPv4 addresses, as the OS routes to private networks and as its name resolves.

    Returns
    -------
    list of str
        Addresses in the order found, without repeats; may include loopback
        (:func:`choose_lan_address` filters).
    """
    found: list[str] = []
    for probe in _ROUTE_PROBES:
        try:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.connect((probe, 9))
                found.append(s.getsockname()[0])
        except OSError:
            pass
    try:
        infos = socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET, socket.SOCK_STREAM)
        found.extend(str(info[4][0]) for info in infos)
    except OSError:
        pass
    return list(dict.fromkeys(found))


def choose_lan_address(candidates: Iterable[str]) -> str | None:
    """The address a phone on the same network can reach, or None.

    A private (RFC 1918) address first, then any other global unicast one, in
    the given order; never loopback, link-local, unspecified or multicast.

    Parameters
    ----------
    candidates : iterable of str
        IPv4 or IPv6 addresses (others are ignored).
    """
    usable: list[ipaddress.IPv4Address | ipaddress.IPv6Address] = []
    for text in candidates:
        try:
            a = ipaddress.ip_address(str(text).strip("[]"))
        except ValueError:
            continue
        if a.is_loopback or a.is_link_local or a.is_unspecified or a.is_multicast or a.is_reserved:
            continue
        usable.append(a)
    for a in usable:
        if a.is_private:
            return str(a)
    return str(usable[0]) if usable else None


def lan_host(given: str | None = None) -> str:
    """The address ``--lan`` binds: ``given`` when it is a specific LAN address, else the one found here.

    Raises
    ------
    TactilizeError
        No address a phone could reach (the machine is on no network), or the
        given host is loopback.
    """
    if given is not None and given not in ("", "0.0.0.0", "::"):
        chosen = choose_lan_address([given])
        if chosen is None:
            raise TactilizeError(f"--host {given}", "not an address other machines can reach (needed by --lan)")
        return chosen
    chosen = choose_lan_address(lan_addresses())
    if chosen is None:
        raise TactilizeError("--lan", "this machine has no network address other than loopback; join a network or give --host ADDRESS")
    return chosen


def page_url(host: str, port: int, secure: bool = False) -> str:
    """The URL to type: ``http(s)://HOST:PORT/`` (IPv6 in brackets)."""
    shown = f"[{host}]" if ":" in host else host
    return f"{'https' if secure else 'http'}://{shown}:{port}/"


def qr_text(url: str) -> str:
    """``url`` as a QR code in text: two modules per character cell, with its quiet zone.

    Light modules are drawn as blocks, so a phone's camera reads it on a dark
    terminal as printed.
    """
    import segno

    out = io.StringIO()
    segno.make(url, error="l", micro=False).terminal(out=out, compact=True, border=2)
    return out.getvalue()


def context_notes(secure: bool) -> list[str]:
    """What works on a phone over this server, one line each (for the terminal and the docs)."""
    if secure:
        return [
            "on the phone: touch and pen input, the drive, vibration (Android Chrome), the audio output and raw pointer "
            "updates all work (HTTPS is a secure context); accept the self-signed certificate once (docs/serve.md)",
        ]
    return [
        "on the phone over plain HTTP: touch and pen input, the drive and vibration (Android Chrome) work;",
        "the audio output (AudioWorklet) and raw pointer updates need a secure context: add --https for them",
    ]
