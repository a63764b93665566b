"""Database URLs without their secrets, for every message, line and file the program writes.

A database URL may carry a password in two places: its user information
(``postgresql://user:secret@host/db``) and its query (``?password=secret``,
which libpq and psycopg accept).  Every place that shows a URL (start-up lines,
``experiment status``, export provenance, error lines of the CLI and of batch
runs) goes through :func:`redact_url`; an exception text that may quote the URL
or the password goes through :func:`redact_text`.

SQLAlchemy's own parser reads the URL where it reads it unambiguously.  It
cannot always: an unescaped ``@`` in a password (``user:p@ss@host``) makes it
split at the first ``@`` and take the rest of the password for the host, and a
string that is no URL at all (a typo) does not parse.  Those go through a
fallback that hides everything up to the last ``@`` of the URL, erring towards
hiding too much (a host or a database name) rather than any part of a secret.
"""

from __future__ import annotations

import os
import re
from urllib.parse import unquote

__all__ = ["MASK", "SECRET_QUERY_KEYS", "ambiguous_user", "redact_url", "redact_text"]

MASK = "***"
#: Query parameters whose value is a secret (compared without case).
SECRET_QUERY_KEYS = frozenset({"password", "passwd", "pwd", "pass", "sslpassword", "secret", "token",
                               "access_token", "auth_token", "api_key", "apikey"})
_QUERY_SECRET = re.compile(r"([?&;]\s*(?:" + "|".join(sorted(SECRET_QUERY_KEYS, key=len, reverse=True))
                           + r")\s*=)[^&;#]*", re.IGNORECASE)


def _split(text: str) -> tuple[str, str] | None:
    """``(scheme, rest)`` of a URL, None for a plain path."""
    scheme, sep, rest = text.partition("://")
    return (scheme, rest) if sep else None


def _parsed(text: str):
    """SQLAlchemy's reading of ``text``, or None where it cannot be trusted."""
    parts = _split(text)
    if parts is None:
        return None
    _, rest = parts
    # Two '@' in the part that may hold a user: SQLAlchemy cuts at the first one,
    # which leaves the end of a password in the host.
    if not rest.startswith("/") and rest.count("@") > 1:
        return None
    try:
        from sqlalchemy.engine import make_url

        return make_url(text)
    except Exception:  # unparsable: an argument error, a bad port...
        return None


def ambiguous_user(url: str | os.PathLike) -> bool:
    """True when ``url``'s user information holds an unescaped ``@``.

    SQLAlchemy then connects to a host made of the end of the password (and
    sends the start of it there): such a URL is refused before it is used,
    asking for the ``@`` to be written ``%40``.
    """
    parts = _split(os.fspath(url) if isinstance(url, os.PathLike) else str(url))
    if parts is None or parts[1].startswith("/"):
        return False
    return _QUERY_SECRET.sub("", parts[1]).count("@") > 1


def _fallback(text: str) -> str:
    text = _QUERY_SECRET.sub(lambda m: m.group(1) + MASK, text)
    parts = _split(text)
    if parts is None:
        head, rest = "", text
    else:
        head, rest = parts[0] + "://", parts[1]
        if rest.startswith("/"):  # no authority (sqlite:///path): no user, no password
            return text
    at = rest.rfind("@")
    if at < 0:
        return text
    userinfo = rest[:at]
    if ":" not in userinfo:
        return text  # a user without a password hides nothing
    user = userinfo.split(":", 1)[0]
    if any(c in user for c in "/?#@"):
        user = MASK
    return f"{head}{user}:{MASK}@{rest[at + 1:]}"


def redact_url(url: str | os.PathLike | None) -> str:
    """``url`` with every password replaced by ``***``.

    Parameters
    ----------
    url : str or path
        An SQLAlchemy URL, a plain file path (returned as it is, since a path
        holds no password), or any text given where a URL was expected.

    Returns
    -------
    str
        The URL with the password of its user information and the values of its
        secret query parameters (:data:`SECRET_QUERY_KEYS`) masked; the rest
        unchanged where nothing needed hiding.
    """
    if url is None:
        return ""
    text = os.fspath(url) if isinstance(url, os.PathLike) else str(url)
    if _split(text) is None:
        # A bare path is a file, except what looks like a URL missing its scheme.
        return _fallback(text) if re.match(r"^[^/\\@:]+:[^@]*@", text) else text
    u = _parsed(text)
    if u is None:
        return _fallback(text)
    secret_keys = [k for k in u.query if k.lower() in SECRET_QUERY_KEYS]
    if u.password is None and not secret_keys:
        return text
    if secret_keys:
        u = u.update_query_dict({k: MASK for k in secret_keys})
    return u.render_as_string(hide_password=True).replace("%2A%2A%2A", MASK)


def _secrets(text: str) -> list[str]:
    """The secret strings in a URL (as written and percent-decoded), longest first."""
    found: list[str] = []
    u = _parsed(text)
    if u is not None:
        if u.password:
            found.append(str(u.password))
        for k, v in u.query.items():
            if k.lower() in SECRET_QUERY_KEYS:
                found.extend([v] if isinstance(v, str) else list(v))
    parts = _split(text)
    rest = parts[1] if parts else text
    for m in _QUERY_SECRET.finditer(rest):
        end = m.end()
        found.append(rest[m.end(1):end])
    bare = _QUERY_SECRET.sub("", rest)
    at = bare.rfind("@")
    if at > 0 and ":" in bare[:at] and not bare.startswith("/"):
        found.append(bare[:at].split(":", 1)[1])
    out = set()
    for s in found:
        for form in (s, unquote(s)):
            # A driver given a misparsed URL quotes pieces of the password (as a host
            # name, say): each piece between separators is masked too.
            for piece in [form, *re.split(r"[@:/?#]", form)]:
                if len(piece) >= 3:  # shorter ones would mask unrelated letters
                    out.add(piece)
    return sorted(out, key=len, reverse=True)


def redact_text(text: str, url: str | os.PathLike | None) -> str:
    """``text`` (an error message) with ``url`` and its secrets masked wherever they appear.

    Parameters
    ----------
    text : str
        A message that may quote ``url`` or its password (a driver's exception).
    url : str or path or None
        The URL the message is about.

    Returns
    -------
    str
    """
    text = str(text)
    if url is None:
        return text
    raw = os.fspath(url) if isinstance(url, os.PathLike) else str(url)
    if raw and raw in text:
        text = text.replace(raw, redact_url(raw))
    for secret in _secrets(raw):
        text = text.replace(secret, MASK)
    return text
