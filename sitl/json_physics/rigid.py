"""Small vector and quaternion helpers on plain tuples (a physics step is a few hundred float
operations: numpy's per-call cost would dominate it). NED earth frame, FRD body frame,
quaternions (w, x, y, z) rotating body vectors into the earth frame."""

from __future__ import annotations

import math

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

GRAVITY = 9.80665
ZERO: Vec = (0.0, 0.0, 0.0)
LEVEL: Quat = (1.0, 0.0, 0.0, 0.0)


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Vec, k: float) -> Vec:
    return (a[0] * k, a[1] * k, a[2] * k)


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a: Vec) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def rotate(q: Quat, v: Vec) -> Vec:
    """Body vector ``v`` in the earth frame."""
    w, x, y, z = q
    # v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + y * tz - z * ty,
            v[1] + w * ty + z * tx - x * tz,
            v[2] + w * tz + x * ty - y * tx)


def unrotate(q: Quat, v: Vec) -> Vec:
    """Earth vector ``v`` in the body frame."""
    return rotate((q[0], -q[1], -q[2], -q[3]), v)


def integrate(q: Quat, gyro: Vec, dt: float) -> Quat:
    """``q`` advanced by the body rates ``gyro`` (rad/s) over ``dt`` (exact for constant rates)."""
    wx, wy, wz = gyro
    rate = math.sqrt(wx * wx + wy * wy + wz * wz)
    if rate < 1e-12:
        return q
    half = 0.5 * rate * dt
    s = math.sin(half) / rate
    dw, dx, dy, dz = math.cos(half), wx * s, wy * s, wz * s
    w, x, y, z = q
    r = (w * dw - x * dx - y * dy - z * dz,
         w * dx + x * dw + y * dz - z * dy,
         w * dy - x * dz + y * dw + z * dx,
         w * dz + x * dy - y * dx + z * dw)
    n = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3])
    return (r[0] / n, r[1] / n, r[2] / n, r[3] / n)


def from_yaw(yaw: float) -> Quat:
    return (math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw))


def yaw_of(q: Quat) -> float:
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def euler(q: Quat) -> Vec:
    """(roll, pitch, yaw) in radians."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return (roll, pitch, yaw_of(q))
