"""Plane geometry of the arena's validation: distances, edge crossings, simple and convex polygons.

Plain Python, not NumPy: arenas are small and loaded once (``sim_world.arena``, ``sim_world.design``).
"""

from __future__ import annotations

import math

Point = tuple[float, float]


def point_segment_distance(p: Point, a: Point, b: Point) -> float:
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / length2))
    return math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy)


def segments_intersect(a: Point, b: Point, c: Point, d: Point) -> bool:
    def orient(p: Point, q: Point, r: Point) -> float:
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    return o1 * o2 < 0 and o3 * o4 < 0


def edges(vertices: list[Point]):
    return zip(vertices, vertices[1:] + vertices[:1])


def polygon_area2(vertices: list[Point]) -> float:
    """Twice the signed area (positive when counter-clockwise)."""
    return sum(a[0] * b[1] - b[0] * a[1] for a, b in edges(vertices))


def is_simple(vertices: list[Point]) -> bool:
    """No repeated vertex and no two non-adjacent edges that cross or touch."""
    n = len(vertices)
    if len(set(vertices)) < n:
        return False
    sides = list(edges(vertices))
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # adjacent through the closing edge
            (a, b), (c, d) = sides[i], sides[j]
            if segments_intersect(a, b, c, d) or min(
                    point_segment_distance(a, c, d), point_segment_distance(b, c, d),
                    point_segment_distance(c, a, b), point_segment_distance(d, a, b)) < 1e-9:
                return False
    return True


def is_convex(vertices: list[Point]) -> bool:
    n = len(vertices)
    signs = set()
    for i in range(n):
        a, b, c = vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]
        cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
        if abs(cross) > 1e-9:
            signs.add(cross > 0)
    if len(signs) != 1:
        return False
    # Turning one way at every vertex is not enough: a pentagram does so too, going round twice.
    turning = 0.0
    for i in range(n):
        a, b, c = vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]
        turning += math.atan2((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]),
                              (b[0] - a[0]) * (c[0] - b[0]) + (b[1] - a[1]) * (c[1] - b[1]))
    return abs(abs(turning) - 2 * math.pi) < 1e-6


def inside_convex(p: Point, vertices: list[Point]) -> bool:
    """True when p is strictly inside the counter-clockwise convex polygon."""
    for a, b in edges(vertices):
        if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) <= 0:
            return False
    return True
