"""Robot description: links, arm kinds and gravity, in SI units.

The arm is planar and moves in a vertical plane, gravity along -y. The first two joints are
actuated and may be revolute (R) or prismatic (P); the third joint is always a passive revolute.

Joint conventions (all angles in radians, counter-clockwise from the x-axis):

* ``RRR``: q1 is link 1's absolute angle, q2 link 2's angle relative to link 1, q3 link 3's
  angle relative to link 2. The third link's base is at
  ``base + l1 u(q1) + l2 u(q1 + q2)`` with ``u(a) = (cos a, sin a)``.
* ``RPR``: q1 is the angle of the revolute joint at the base, q2 the prismatic extension
  along ``u(q1)`` (the distance from the base to the third joint, > 0); q3 is relative to q1.
  Link 2 is a rod of length l2 sliding along link 1, its far end carrying joint 3.
* ``PRR``: q1 is a horizontal slide (a carriage on a rail along +x), q2 the absolute angle of
  link 2, q3 link 3's angle relative to link 2.
* ``PPR``: q1 slides along +x, q2 slides along +y (a gantry); q3 is link 3's absolute angle.

In every kind the third link's angle is ``theta = (sum of revolute joint angles)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

G0 = 9.81
"""Standard gravity used by the paper [m/s^2]."""

ARM_KINDS = ("RRR", "RPR", "PRR", "PPR")

BRANCHES = {
    "RRR": ("elbow_up", "elbow_down"),
    "PRR": ("forward", "backward"),
    "RPR": (None,),
    "PPR": (None,),
}
"""Inverse-kinematics branches per arm kind.

``elbow_up``: the elbow lies to the left of the base-to-wrist line (q2 < 0 for a target on
the right of the base). ``forward``/``backward``: link 2 of a PRR arm points to +x / -x of the
carriage (cos q2 > 0 / < 0). RPR (q2 > 0) and PPR have a single branch.
"""


@dataclass(frozen=True)
class Link:
    """A rigid link.

    Parameters
    ----------
    length : float
        Distance between the link's two joints [m].
    mass : float
        Mass [kg].
    com : float or None
        Distance of the centre of mass from the link's proximal joint [m]; ``None`` means a
        uniform rod, ``length / 2``.
    inertia : float or None
        Barycentric moment of inertia about the axis normal to the plane [kg m^2]; ``None``
        means a uniform thin rod, ``mass * length**2 / 12``.
    """

    length: float
    mass: float
    com: float | None = None
    inertia: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length) and self.length > 0):
            raise ValueError(f"link length must be positive, got {self.length!r} m")
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"link mass must be positive, got {self.mass!r} kg")
        if self.com is not None and not np.isfinite(self.com):
            raise ValueError(f"link centre of mass must be finite, got {self.com!r} m")
        if self.inertia is not None and not (np.isfinite(self.inertia) and self.inertia >= 0):
            raise ValueError(f"link inertia must be >= 0, got {self.inertia!r} kg m^2")

    @property
    def d(self) -> float:
        """Distance of the centre of mass from the proximal joint [m]."""
        return self.length / 2 if self.com is None else float(self.com)

    @property
    def I(self) -> float:  # noqa: E743 - the paper's symbol
        """Barycentric moment of inertia [kg m^2]."""
        return self.mass * self.length**2 / 12 if self.inertia is None else float(self.inertia)


@dataclass(frozen=True)
class Arm:
    """A three-link planar arm with a passive revolute third joint.

    Parameters
    ----------
    kind : str
        One of ``RRR``, ``RPR``, ``PRR``, ``PPR``: the kinds of the three joints.
    links : tuple of Link
        The three links, base to tip.
    base : tuple of float
        Position of the first joint in the plane [m].
    gravity : float
        Gravitational acceleration along -y [m/s^2].
    branch : str or None
        Inverse-kinematics branch, one of ``BRANCHES[kind]``; ``None`` takes the first.
    """

    kind: str
    links: tuple[Link, Link, Link]
    base: tuple[float, float] = (0.0, 0.0)
    gravity: float = G0
    branch: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ARM_KINDS:
            raise ValueError(f"arm kind must be one of {ARM_KINDS}, got {self.kind!r}")
        if len(self.links) != 3:
            raise ValueError(f"an arm has exactly 3 links, got {len(self.links)}")
        object.__setattr__(self, "links", tuple(self.links))
        object.__setattr__(self, "base", (float(self.base[0]), float(self.base[1])))
        allowed = BRANCHES[self.kind]
        branch = allowed[0] if self.branch is None else self.branch
        if branch not in allowed:
            raise ValueError(
                f"branch of a {self.kind} arm must be one of {allowed}, got {branch!r}"
            )
        object.__setattr__(self, "branch", branch)
        d3 = self.links[2].d
        if not d3 > 0:
            raise ValueError(
                f"the third link's centre of mass must be beyond its joint (d3 > 0), got {d3} m"
            )

    @property
    def branch_sign(self) -> float:
        """The branch as a sign: RRR ``elbow_down`` and PRR ``forward`` +1, RRR ``elbow_up`` and
        PRR ``backward`` -1 (the sign of sin q2, resp. cos q2); +1 for RPR and PPR."""
        return -1.0 if self.branch in ("elbow_up", "backward") else 1.0

    @property
    def revolute(self) -> tuple[bool, bool, bool]:
        """Which joints are revolute (angles in rad, limits in deg in files); the third always."""
        return (self.kind[0] == "R", self.kind[1] == "R", True)

    @property
    def K(self) -> float:
        """Distance of the third link's centre of percussion from its joint [m].

        ``K = (I3 + m3 d3^2) / (m3 d3)``; ``2 l3 / 3`` for a uniform rod.
        """
        l3 = self.links[2]
        return (l3.I + l3.mass * l3.d**2) / (l3.mass * l3.d)


def uniform_rod(length: float, mass: float) -> Link:
    """A uniform thin rod of the given length [m] and mass [kg]."""
    return Link(length=length, mass=mass)


def paper_arm(masses: tuple[float, float, float], branch: str = "elbow_up") -> Arm:
    """The paper's 3R arm: base at the origin, l1 = l2 = 1.5 m, l3 = 1 m, uniform rods.

    Parameters
    ----------
    masses : tuple of float
        Link masses (m1, m2, m3) [kg].
    branch : str
        ``elbow_up`` or ``elbow_down``.
    """
    lengths = (1.5, 1.5, 1.0)
    return Arm(
        kind="RRR",
        links=tuple(uniform_rod(length, m) for length, m in zip(lengths, masses, strict=True)),
        branch=branch,
    )
