"""Fits radius profiles to road polylines and finds their curves (T/ITS 0091-2018, 3.2-3.8).

A road centreline arrives as a polyline: a dense SUMO lane shape (vertices 0.5-1 m
apart, coordinates rounded to 1 cm) or a sparse map way (nodes 5-30 m apart with
decimetre-level noise). The radius through three consecutive vertices is useless on
both: on a dense shape a 1 cm rounding error bends a 0.5 m chord by more than a
500 m curve does. This package therefore models the road as roads are designed (and
as OpenDRIVE and ADAS horizons exchange them): curvature piecewise linear in arc
length, i.e. straights, arcs and the clothoids between them, and fits that model to
the whole polyline:

1. Each chord's heading belongs to the arc length of its midpoint (on a circle the
   chord is parallel to the tangent there), so heading against arc length is
   continuous and piecewise linear, its slope being the curvature.
2. The heading is cut into parts of constant curvature by binary segmentation: a
   part is split where two lines fit its headings significantly better than one,
   judged against the coordinate noise estimated from the polyline itself.
3. Each knot (curvature step) is moved to where the lines fitted to its two parts
   intersect, chords straddling it are left out of the fits, and neighbouring parts
   that one line fits as well are merged. Two lines that do not cross mean a curve
   shorter than its neighbours' resolution; the chords around it become its own part.
4. The chords of the curved parts are converted to arc lengths (a chord of length c
   on radius R spans ``2 R asin(c / 2R)``) and the parts are fitted once more.
5. Where the parts of a dense polyline form a staircase (a step, or short stairs of
   intermediate radius), a clothoid is fitted in its place and kept where the headings
   prefer it (:mod:`csws.curvature.transitions`); the whole profile is then refitted
   with its heading and curvature continuous.

A curve (3.4, 3.5) is then a maximal stretch turning one way with a radius no larger
than the warning curvature radius R_c, its ends inside clothoids where they cross R_c
(:mod:`csws.curvature.curves`); its parts are its arcs, those of a single (3.7) or
multi curve (3.8), and short pieces of its clothoids: its curvature points (3.11).

All polylines of a network are processed together in flat arrays, so the number of
numpy operations does not grow with the number of lanes. Sparse polylines (map ways,
see :mod:`csws.curvature.polish`) are fitted in a few batches of similar chord counts,
each step for all polylines of a batch and all their trial knot positions at once. A
map way's chords are too few and too noisy for the fit of their headings to be the
last word, so the road it finds is finally fitted to the nodes themselves, in the plane
(:mod:`csws.curvature.road`): the maximum-likelihood road under isotropic node noise, exact on
exact nodes, with straights tried at its ends where the heading fit ran a curve into one.
"""

from .cache import cached_radius_profiles, profile_cache_dir
from .curves import checked_warning_radius_m, curves_from_profile
from .fitting import find_curves, radius_profile, radius_profiles, three_point_radius
from .profile import (
    ConstantRadiusPart,
    Curve,
    ProfilePart,
    RadiusProfile,
    profile_along,
    profile_from_parts,
    straight_profile,
)

__all__ = [
    "ProfilePart",
    "RadiusProfile",
    "profile_along",
    "profile_from_parts",
    "straight_profile",
    "ConstantRadiusPart",
    "Curve",
    "radius_profile",
    "radius_profiles",
    "cached_radius_profiles",
    "profile_cache_dir",
    "checked_warning_radius_m",
    "curves_from_profile",
    "find_curves",
    "three_point_radius",
]
