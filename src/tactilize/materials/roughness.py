"""Micro-roughness: the relief below a picture's resolution, drawn where the tip is.

A material's fine roughness (RMS height and correlation length, docs/references.md,
section 11 (micro-roughness)) is a Gaussian random surface with a Gaussian
autocorrelation.  It is made as a sum of Gaussian bumps on a square lattice fixed
to the real surface, each bump's weight a normal number drawn from a hash of its
lattice node and the material's name: the same spot always has the same height,
whichever way it is stroked and on every run, with no tile that repeats.

What the tip feels of it is that surface seen through the tip and the contact
(:mod:`.relief`): Gaussian low-passes, which a sum of Gaussians takes exactly.
A field of correlation length l (Gaussian bumps of standard deviation l / 2)
through a low-pass of standard deviation s is the same kind of field, of
standard deviation sigma = sqrt(l^2 / 4 + s^2) and RMS rms (l / 2) / sigma, so only
the filtered field is ever evaluated, on a lattice of spacing sigma (a sum of
Gaussians on a lattice no wider than their standard deviation is stationary to
1e-4 in variance).

Units: SI (m).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["MicroRoughness"]

#: Nodes beyond this many standard deviations add under 1e-4 of a bump.
_REACH = 3
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(z: np.ndarray) -> np.ndarray:
    """A 64-bit integer hash (the splitmix64 finaliser): neighbouring nodes get unrelated bits.
    Its products wrap modulo 2^64 by design."""
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * _M1
        z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@dataclass(frozen=True)
class MicroRoughness:
    """A material's micro-roughness as the tip feels it, a function of position.

    Attributes
    ----------
    rms_m : float
        RMS height of the roughness before the tip [m].
    correlation_length_m : float
        Its correlation length [m].
    filter_sigma_m : float
        Standard deviation of the Gaussian low-pass of tip and contact [m] on the surface.
    seed : int
        The material's own draw (from its name).

    References
    ----------
    .. [1] docs/references.md, section 11 (micro-roughness).
    """

    rms_m: float
    correlation_length_m: float
    filter_sigma_m: float
    seed: int

    @classmethod
    def of(cls, name: str, rms_m: float, correlation_length_m: float, filter_sigma_m: float) -> "MicroRoughness":
        """The roughness of the material ``name`` (its seed is the name's CRC-32, the same every run)."""
        return cls(float(rms_m), float(correlation_length_m), float(filter_sigma_m), zlib.crc32(name.encode()))

    @property
    def sigma_m(self) -> float:
        """Standard deviation of the felt field's Gaussian bumps [m]."""
        return math.hypot(0.5 * self.correlation_length_m, self.filter_sigma_m)

    @property
    def felt_rms_m(self) -> float:
        """RMS height of the roughness the tip follows [m]."""
        return self.rms_m * 0.5 * self.correlation_length_m / self.sigma_m

    @property
    def spacing_m(self) -> float:
        """Spacing of the lattice of bumps [m] (see the module docstring)."""
        return self.sigma_m

    @property
    def node_weight_m(self) -> float:
        """Height of a node's bump [m] per unit of its normal number: the field's RMS is then
        :attr:`felt_rms_m` (unit Gaussians of standard deviation sigma on a lattice of spacing
        a sum to a variance of pi sigma^2 / a^2)."""
        return self.felt_rms_m * self.spacing_m / (math.sqrt(math.pi) * self.sigma_m)

    @property
    def seed_word(self) -> int:
        """The 64-bit word every node's hash is mixed with (from :attr:`seed`)."""
        return (self.seed * int(_GOLDEN)) & 0xFFFFFFFFFFFFFFFF

    def to_dict(self) -> dict[str, Any]:
        """Everything :meth:`height_m` reads, for a renderer in another language: the attributes,
        the lattice (``spacing_m``, ``sigma_m``, ``node_weight_m`` [m], ``reach`` nodes either
        side) and ``seed_word`` as 16 hexadecimal digits."""
        return {"rms_m": self.rms_m, "correlation_length_m": self.correlation_length_m,
                "filter_sigma_m": self.filter_sigma_m, "seed": self.seed, "spacing_m": self.spacing_m,
                "sigma_m": self.sigma_m, "node_weight_m": self.node_weight_m, "reach": _REACH,
                "seed_word": f"{self.seed_word:016x}"}

    def height_m(self, x_m: Any, y_m: Any) -> np.ndarray:
        """Height of the felt roughness [m] at positions on the real surface [m]."""
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        out = np.zeros(np.broadcast(x, y).shape)
        if self.rms_m <= 0 or out.size == 0:
            return out
        sigma = self.sigma_m
        spacing = self.spacing_m
        weight = self.node_weight_m
        u, v = x / spacing, y / spacing
        iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        fu, fv = u - iu, v - iv
        seed = np.uint64(self.seed_word)
        k = -0.5 * (spacing / sigma) ** 2
        with np.errstate(over="ignore"):  # the node hashes wrap modulo 2^64 by design
            for du in range(-_REACH, _REACH + 1):
                gu = np.exp(k * (fu - du) ** 2)
                nu = (iu + du).astype(np.uint64) * np.uint64(0x9E3779B1)
                for dv in range(-_REACH, _REACH + 1):
                    h = _mix(nu ^ ((iv + dv).astype(np.uint64) * np.uint64(0x85EBCA77)) ^ seed)
                    out += _normal(h) * gu * np.exp(k * (fv - dv) ** 2)
        return out * weight


def _normal(h: np.ndarray) -> np.ndarray:
    """A standard normal number from each 64-bit hash (Box-Muller on its two 32-bit halves)."""
    lo = ((h & np.uint64(0xFFFFFFFF)).astype(np.float64) + 0.5) / 4294967296.0
    hi = ((h >> np.uint64(32)).astype(np.float64) + 0.5) / 4294967296.0
    return np.sqrt(-2.0 * np.log(lo)) * np.cos(2.0 * math.pi * hi)
