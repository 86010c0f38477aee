"""Which joints are the legs, arms and head: by name on any naming convention, else by structure.

Names are read after the namespace (``mixamorig:``, ``Beta:``, ``rig|``) and split into words
(``Character1_LeftUpLeg`` -> character 1 left up leg, ``lThighBend`` -> l thigh bend,
``FootLeft``, ``foot.L``, ``thigh_l``, ``Bip01 L Foot``, ``LEFT_HIP#``, ``lhipjoint``). One word, or a
leading ``l``/``r`` glued to a known part (CMU's ``lfemur``, DAZ's ``lShin``), gives the side; the
rest of the words, joined, give the part. Helper joints (``*_RIGMESH``, IK targets, ``*_End``
tips) are never limbs.

When names do not find two feet, the structure does (:func:`limbs_by_structure`): the skeleton's
mirrored pairs of unbranched chains are limbs; legs are the pair whose tips are lowest over the
motion, arms the pair after it, the head the tip of the longest other chain from the arms' branch.
A skeleton with no such pair, or with two pairs of legs (a quadruped), is not a biped.
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field

import numpy as np

SIDES = ("left", "right")
_SIDE_WORDS = {"left": "left", "l": "left", "lft": "left", "lt": "left",
               "right": "right", "r": "right", "rgt": "right", "rt": "right"}
_HELPER_WORDS = {"rigmesh", "helper", "ik", "fk", "pole", "target", "ctrl", "control", "nub", "end", "tip", "site",
                 "mch", "twistend", "roll", "effector", "null", "dummy", "reference", "ref", "locator"}
# part patterns, tried on the side-free words joined without separators (lower case)
PARTS = {  # order matters: "upleg" is a thigh before "leg" is a shank, "forearm" before "arm"
    "toe": r"toe|ball|metatars|phalange",
    "foot": r"foot|ankle",
    "thigh": r"thigh|upleg|upperleg|femur|hip(?!s|joint)|uleg",
    "shank": r"shin|calf|knee|tibia|lowerleg|leg|crus",
    "hand": r"hand|wrist|palm",
    "forearm": r"forearm|lowerarm|elbow|radius|ulna|lowarm",
    "upperarm": r"upperarm|humerus|shldr|(?<!fore)arm|uparm",
    "clavicle": r"clavicle|collar|shoulder|scapula",
    "head": r"head|skull|cranium",
    "neck": r"neck",
}
_FINGER = re.compile(r"thumb|index|middle|ring|pinky|pinkie|finger|carpal|digit|inhand", re.I)
_GLUED = re.compile(r"^([lr])(" + "|".join(["foot", "ankle", "toe", "shin", "calf", "knee", "tibia", "leg", "thigh",
                                            "upleg", "femur", "hip", "hand", "wrist", "forearm", "radius", "ulna",
                                            "humerus", "shldr", "arm", "shoulder", "clavicle", "collar", "uparm",
                                            "lowarm", "metatarsal", "fingers", "thumb", "big"]) + ")")


def name_words(name: str) -> list[str]:
    """Lower-case words of a joint name, after its namespace."""
    base = re.split(r"[:|]", name)[-1]
    words = []
    for piece in re.split(r"[^A-Za-z0-9]+", base):
        # camelCase and digit boundaries: LeftUpLeg, lThighBend, LHipJoint, Spine1
        words += re.findall(r"[A-Z]+(?=[A-Z][a-z]{2,})|[A-Z]?[a-z]+|[A-Z]+|\d+", piece)
    return [w.lower() for w in words if w]


@functools.lru_cache(maxsize=8192)  # a rig is read for its limbs often (each conform), by the same names
def side_and_part(name: str) -> tuple[str | None, str]:
    """(side or None, the rest of the name's words joined) of a joint name."""
    words = name_words(name)
    side = None
    rest = []
    for w in words:
        if side is None and w in _SIDE_WORDS:
            side = _SIDE_WORDS[w]
        else:
            rest.append(w)
    if side is None and rest:
        m = _GLUED.match(rest[0])
        if m:
            side = "left" if m.group(1) == "l" else "right"
            rest[0] = rest[0][1:]
    return side, "".join(w for w in rest if not w.isdigit() or len(rest) == 1)


def is_helper(name: str) -> bool:
    return bool(set(name_words(name)) & _HELPER_WORDS)


@functools.lru_cache(maxsize=8192)
def part_of(name: str) -> str | None:
    """The body part a joint name names ('foot', 'shank', ..., 'head'), or None; fingers are None."""
    if is_helper(name):
        return None
    _, rest = side_and_part(name)
    if _FINGER.search(rest):
        return None
    for part, pattern in PARTS.items():
        if re.search(pattern, rest):
            return part
    return None


@dataclass
class Limbs:
    """Joint indices of a biped's limbs. ``legs[side]`` = (thigh, shank, foot, toe), ``arms[side]`` =
    (upper arm, forearm, hand) (None where a rig has no such joint); ``head`` the head joint (or the
    top of the neck), ``how`` 'names' or 'structure'."""

    legs: dict[str, tuple[int, int, int, int]]
    arms: dict[str, tuple[int, int, int]] = field(default_factory=dict)
    head: int | None = None
    how: str = "names"

    @property
    def feet(self) -> dict[str, tuple[int, int]]:
        return {s: (leg[2], leg[3]) for s, leg in self.legs.items()}


class NotBiped(Exception):
    """The skeleton is not a two-legged character (a quadruped, a prop, an arm)."""


LIMB_PARTS = ("foot", "toe", "shank", "thigh", "hand", "forearm", "upperarm", "head", "neck")
MAX_PROP_JOINTS = 3


def descendants(parents, j) -> list[int]:
    """``j`` and every joint below it (parents come before their children)."""
    out, inside = [j], {j}
    for k in range(j + 1, len(parents)):
        if parents[k] in inside:
            out.append(k)
            inside.add(k)
    return out


def props_below(skeleton, j) -> list[int] | None:
    """When joint ``j`` carries the body through one child and holds only props or helpers beside
    it (IK targets, a reference marker: subtrees of at most 3 joints, no limb among them and no
    mirrored pair), the joints of those props; [] when it has a single child; None otherwise."""
    kids = skeleton.children(j)
    if len(kids) <= 1:
        return [] if kids else None
    trees = {k: descendants(skeleton.parents, k) for k in kids}
    body = max(kids, key=lambda k: len(trees[k]))
    others = [k for k in kids if k != body]
    if any(len(trees[k]) > MAX_PROP_JOINTS for k in others):
        return None
    if any(part_of(skeleton.names[m]) in LIMB_PARTS for k in others for m in trees[k]):
        return None
    for a in range(len(others)):
        for b in range(a + 1, len(others)):
            ca, cb = trees[others[a]], trees[others[b]]
            if _mirrored(skeleton, ca, cb):  # two legs of three joints each are not props
                return None
    return [m for k in others for m in trees[k]]


def floating_base(skeleton) -> int:
    """The joint that carries the floating base: the root, or the joint below a chain of dummy
    roots (roots whose one child carries the body, beside props at most, and that have no end
    site; see :mod:`retime.motion.conform`)."""
    return base_and_props(skeleton)[0]


def base_and_props(skeleton) -> tuple[int, list[int]]:
    """(:func:`floating_base`, the prop joints beside the body under the dummy roots above it)."""
    j, props = 0, []
    sizes = _subtree_sizes(skeleton.parents)  # once: a long chain is walked joint by joint
    with_end_site = {e for e, _ in skeleton.end_sites}
    while skeleton.n_joints - j > 2:
        here = props_below(skeleton, j)
        if here is None or j in with_end_site:
            break
        kids = [k for k in skeleton.children(j) if k not in here]
        if len(kids) != 1 or sizes[kids[0]] < 3:
            break
        props += here
        j = kids[0]
    return j, props


def _subtree_sizes(parents) -> list[int]:
    """How many joints each joint's subtree holds, itself included (parents come before children)."""
    sizes = [1] * len(parents)
    for k in range(len(parents) - 1, 0, -1):
        if parents[k] >= 0:
            sizes[parents[k]] += sizes[k]
    return sizes


def _depth(parents, j):
    d = 0
    while parents[j] >= 0:
        j = parents[j]
        d += 1
    return d


def _children(parents):
    kids = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            kids[p].append(j)
    return kids


def _ancestors(parents, j):
    out = []
    while parents[j] >= 0:
        j = int(parents[j])
        out.append(j)
    return out


def _named(skeleton, part, side):
    cands = [j for j, n in enumerate(skeleton.names) if part_of(n) == part and side_and_part(n)[0] == side]
    return min(cands, key=lambda j: (_depth(skeleton.parents, j), j)) if cands else None


def _toe_below(skeleton, foot, kids):
    toes = [c for c in kids[foot] if part_of(skeleton.names[c]) == "toe"]
    if toes:
        return toes[0]
    real = [c for c in kids[foot] if not is_helper(skeleton.names[c]) and not _FINGER.search(skeleton.names[c])]
    return real[0] if len(real) == 1 else foot


def _top_of(skeleton, j, part):
    """The highest of the joints named ``part`` in a row from ``j`` up (a forearm's bend joint above
    its twist joint: the elbow is where the bone starts)."""
    while skeleton.parents[j] > 0 and part_of(skeleton.names[int(skeleton.parents[j])]) == part:
        j = int(skeleton.parents[j])
    return j


def _leg_chain(skeleton, foot, kids):
    """(thigh, shank, foot, toe) from the foot joint up, by names where they say, else by position."""
    up = _ancestors(skeleton.parents, foot)
    shank = next((_top_of(skeleton, a, "shank") for a in up[:3] if part_of(skeleton.names[a]) == "shank"),
                 up[0] if up else foot)
    above = _ancestors(skeleton.parents, shank)
    thigh = next((a for a in above[:3] if part_of(skeleton.names[a]) == "thigh"), above[0] if above else shank)
    return (thigh, shank, foot, _toe_below(skeleton, foot, kids))


def _arm_chain(skeleton, hand):
    up = _ancestors(skeleton.parents, hand)
    fore = next((_top_of(skeleton, a, "forearm") for a in up[:3] if part_of(skeleton.names[a]) == "forearm"),
                up[0] if up else hand)
    above = _ancestors(skeleton.parents, fore)
    upper = next((a for a in above[:3] if part_of(skeleton.names[a]) == "upperarm"), above[0] if above else fore)
    return (upper, fore, hand)


IN_LINE_DEG = 15.0  # a joint whose bone stays this close to the next bone's direction is part of that bone


def bone_joints(skeleton, positions, end: int, stop=()) -> list[int]:
    """The joints that carry the bone ending at joint ``end`` (a knee, an ankle, an elbow), from its
    parent up: the parent, then each joint above whose own bone stays in line with that bone (twist
    and bend joints: within :data:`IN_LINE_DEG` in 95 % of the frames of the world ``positions``
    (F, J, 3), or of zero length), whatever the joints are named. Never the root, nor a joint above
    any of ``stop`` (the other limbs' ends): a pelvis-side bone (CMU's hip joint) bends away from
    the thigh, so it is not the thigh."""
    parents = skeleton.parents
    top = int(parents[end])
    if top <= 0:
        return [top] if top == 0 else []
    run = [top]
    main = positions[:, end] - positions[:, top]  # (F, 3)
    size = float(np.median(np.linalg.norm(main, axis=1)))
    while True:
        p = int(parents[run[-1]])
        if p <= 0 or any(p in _ancestors(parents, s) for s in stop):
            return run
        bone = positions[:, run[-1]] - positions[:, p]
        length = np.linalg.norm(bone, axis=1)
        if np.median(length) > 1e-3 * size:
            cos = np.sum(bone * main, axis=1) / np.maximum(length * np.linalg.norm(main, axis=1), 1e-12)
            if np.percentile(cos, 5) < np.cos(np.radians(IN_LINE_DEG)):
                return run
        run.append(p)


def limbs_by_name(skeleton) -> Limbs | None:
    """Limbs found by joint names, or None when either foot is not named."""
    kids = _children(skeleton.parents)
    feet = {s: _named(skeleton, "foot", s) for s in SIDES}
    if any(f is None for f in feet.values()) or feet["left"] == feet["right"]:
        return None
    for s in SIDES:  # a second foot on one side, not below the first: front and hind feet
        others = [j for j, n in enumerate(skeleton.names) if part_of(n) == "foot" and side_and_part(n)[0] == s
                  and feet[s] not in _ancestors(skeleton.parents, j) and j != feet[s]]
        if others:
            raise NotBiped(f"two {s} feet ({skeleton.names[feet[s]]}, {skeleton.names[others[0]]}): four legs")
    legs = {s: _leg_chain(skeleton, feet[s], kids) for s in SIDES}
    arms = {}
    for s in SIDES:
        hand = _named(skeleton, "hand", s)
        if hand is not None and hand not in legs["left"] + legs["right"]:
            arms[s] = _arm_chain(skeleton, hand)
    head = _named(skeleton, "head", None)
    if head is None:
        head = _named(skeleton, "neck", None)
        if head is not None:  # the top of the neck chain
            while len(kids[head]) == 1 and part_of(skeleton.names[kids[head][0]]) in ("neck", "head", None):
                head = kids[head][0]
    if head is None and len(arms) == 2:
        head = _spine_top(skeleton, kids, arms)
    return Limbs(legs=legs, arms=arms, head=head, how="names")


def _spine_top(skeleton, kids, arms):
    """The head of a rig that names its neck and head as spine joints (Rigify: DEF-spine.004 to .006 above
    the chest, DEF-spine.003, that carries the shoulders): the top of the row of joints named as the arms'
    branch is (the same words, numbers aside) going on above it, or None when the row ends there."""
    right = _ancestors(skeleton.parents, arms["right"][0])
    branch = next((a for a in _ancestors(skeleton.parents, arms["left"][0])  # the first unsided one (Rigify's
                   if a in right and side_and_part(skeleton.names[a])[0] is None), None)  # right shoulder may hang
    # from its left one: joined by geometry, in the add-on and the FBX/glTF bridge)
    if branch is None:
        return None
    stem = side_and_part(skeleton.names[branch])
    top = branch
    while True:
        row = [c for c in kids[top] if side_and_part(skeleton.names[c]) == stem]
        if len(row) != 1:
            break
        top = row[0]
    return top if top != branch else None


# ---------------------------------------------------------------------------------------------
# structure


def _chains(skeleton, kids):
    """Unbranched chains hanging from a branch joint: (branch, [joints down to the tip])."""
    out = []
    for b in range(skeleton.n_joints):
        if len(kids[b]) < 2 and skeleton.parents[b] >= 0:
            continue
        for c in kids[b]:
            chain = [c]
            while len(kids[chain[-1]]) == 1:
                chain.append(kids[chain[-1]][0])
            out.append((b, chain))
    return out


def _profile(skeleton, chain):
    return np.array([np.linalg.norm(skeleton.offsets[j]) for j in chain])


def _mirrored(skeleton, a, b):
    pa, pb = _profile(skeleton, a), _profile(skeleton, b)
    if len(pa) != len(pb) or len(pa) < 3:
        return False
    scale = max(pa.sum(), pb.sum(), 1e-9)
    return bool(np.abs(pa - pb).max() <= 0.05 * scale)


def limbs_by_structure(skeleton, positions, up) -> Limbs:
    """Legs, arms and head from the skeleton's shape and the motion's world ``positions`` (F, J, 3)
    with ``up`` (3,) the world up direction; raises :class:`NotBiped`."""
    kids = _children(skeleton.parents)
    chains = _chains(skeleton, kids)
    height = positions @ np.asarray(up, dtype=float)  # (F, J)
    pairs = []
    for i in range(len(chains)):
        for k in range(i + 1, len(chains)):
            (bi, ci), (bk, ck) = chains[i], chains[k]
            if bi == bk and _mirrored(skeleton, ci, ck):
                tip = float(np.median(np.minimum(height[:, ci[-1]], height[:, ck[-1]])))
                pairs.append((tip, bi, ci, ck))
    if not pairs:
        raise NotBiped("no two mirrored limb chains")
    pairs.sort(key=lambda p: p[0])
    floor = float(np.percentile(height.min(axis=1), 5))
    span = float(np.percentile(height.max(axis=1) - height.min(axis=1), 50)) or 1.0
    low = [p for p in pairs if p[0] - floor < 0.15 * span]
    if len(low) > 1:
        raise NotBiped("two pairs of limbs reach the floor (four legs)")
    _, _, la, lb = pairs[0]

    def leg(chain):  # thigh, shank, foot, toe: the last four joints, or three without a toe
        return tuple(chain[-4:]) if len(chain) >= 4 else (chain[-3], chain[-2], chain[-1], chain[-1])

    legs = [leg(la), leg(lb)]
    arms, head = [], None
    if len(pairs) > 1:
        _, branch, aa, ab = pairs[1]
        arms = [tuple(aa[-3:]), tuple(ab[-3:])]
        others = [c for b, c in chains if b == branch and c is not aa and c is not ab]
        if others:
            head = max(others, key=len)[-1]
    # left = up x forward; forward = the feet's heel-to-toe direction
    fwd = np.zeros(3)
    for lg in legs:
        fwd += np.median(positions[:, lg[3]] - positions[:, lg[2]], axis=0)
    lateral = np.cross(up, fwd)
    side_of = {}
    for k, lg in enumerate(legs):
        side_of[k] = float(np.median((positions[:, lg[2]] - positions[:, 0]) @ lateral))
    order = ("left", "right") if side_of[0] >= side_of[1] else ("right", "left")
    out_legs = {order[0]: legs[0], order[1]: legs[1]}
    out_arms = {}
    if arms:
        a0 = float(np.median((positions[:, arms[0][2]] - positions[:, 0]) @ lateral))
        a1 = float(np.median((positions[:, arms[1][2]] - positions[:, 0]) @ lateral))
        aorder = ("left", "right") if a0 >= a1 else ("right", "left")
        out_arms = {aorder[0]: arms[0], aorder[1]: arms[1]}
    return Limbs(legs=out_legs, arms=out_arms, head=head, how="structure")


def nearest_pair_tips(skeleton) -> tuple[int, int] | None:
    """Tips of the mirrored chain pair that branches closest to the root (a biped's feet, before
    the up axis is known), or None."""
    kids = _children(skeleton.parents)
    chains = _chains(skeleton, kids)
    best = None
    for i in range(len(chains)):
        for k in range(i + 1, len(chains)):
            (bi, ci), (bk, ck) = chains[i], chains[k]
            if bi == bk and _mirrored(skeleton, ci, ck):
                key = (_depth(skeleton.parents, bi), -len(ci))
                if best is None or key < best[0]:
                    best = (key, ci[-1], ck[-1])
    return None if best is None else (best[1], best[2])


def find_limbs(skeleton, positions=None, up=None) -> Limbs:
    """Limbs by name (:func:`limbs_by_name`), else by structure (:func:`limbs_by_structure`, which
    needs the motion's world ``positions`` and ``up``); raises :class:`NotBiped`."""
    limbs = limbs_by_name(skeleton)
    if limbs is not None:
        return limbs
    if positions is None:
        raise NotBiped("no joints named like feet, and no motion to find them by structure")
    return limbs_by_structure(skeleton, positions, np.asarray(up, dtype=float))
