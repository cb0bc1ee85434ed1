"""Point data for kernel tests: reference points on flat, cylindrical and
spherical surfaces, in non-orthonormal coordinates, with random states."""

import numpy as np


def flat(theta=(0.3, -0.2)):
    """R = (t1, t2, 0); derivatives (R_1, R_2, R_11, R_12, R_22)."""
    R1 = np.array([1.0, 0.0, 0.0])
    R2 = np.array([0.0, 1.0, 0.0])
    z = np.zeros(3)
    return np.concatenate([R1, R2, z, z, z])


def cylinder(radius=1.0, theta=0.4):
    """R = (rho cos t, rho sin t, z): outward normal, H = -1/(2 rho), K = 0."""
    c, s = np.cos(theta), np.sin(theta)
    R1 = radius * np.array([-s, c, 0.0])
    R2 = np.array([0.0, 0.0, 1.0])
    R11 = radius * np.array([-c, -s, 0.0])
    z = np.zeros(3)
    return np.concatenate([R1, R2, R11, z, z])


def sphere(radius=1.0, theta=0.9, phi=0.3):
    """R = rho (sin t cos p, sin t sin p, cos t): outward normal, H = -1/rho, K = 1/rho^2."""
    st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)
    R1 = radius * np.array([ct * cp, ct * sp, -st])
    R2 = radius * np.array([-st * sp, st * cp, 0.0])
    R11 = radius * np.array([-st * cp, -st * sp, -ct])
    R12 = radius * np.array([-ct * sp, ct * cp, 0.0])
    R22 = radius * np.array([-st * cp, -st * sp, 0.0])
    return np.concatenate([R1, R2, R11, R12, R22])


SURFACES = {"flat": flat, "cylinder": cylinder, "sphere": sphere}

# a non-orthonormal change of coordinates theta = S xi
SKEW = np.array([[1.3, 0.4], [-0.2, 0.8]])


def reparametrize(v, S=SKEW):
    """(r_a, r_ab) in coordinates xi with theta = S xi."""
    r = v[:6].reshape(2, 3)
    rab = np.array([[v[6:9], v[9:12]], [v[9:12], v[12:15]]])
    r_new = S.T @ r                               # r_{,i} = r_a S_ai
    rab_new = np.einsum("ai,bj,abk->ijk", S, S, rab)
    return np.concatenate([r_new[0], r_new[1], rab_new[0, 0], rab_new[0, 1], rab_new[1, 1]])


def reparametrize_field(d, S=SKEW):
    """Surface derivatives d[a] of a field, in coordinates xi: d_i = d_a S_ai."""
    return np.einsum("ai,a...->i...", S, d)


def rotate(v, Q):
    return (v.reshape(5, 3) @ Q.T).reshape(15)


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.linalg.det(q))


def random_state(rng, surface, with_g1=True, with_loads=True, amp=0.08):
    """Reference, current state, growth and loads at a random admissible point."""
    ref = reparametrize(SURFACES[surface]())
    v = ref + amp * rng.standard_normal(15)
    G0 = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    kw = dict(G0=G0)
    kw["G1"] = 0.3 * rng.standard_normal((3, 3)) if with_g1 else np.zeros((3, 3))
    kw["dG0"] = 0.2 * rng.standard_normal((2, 3, 3))
    if with_loads:
        kw["qbar"] = 0.1 * rng.standard_normal(3)
        kw["m"] = 0.05 * rng.standard_normal(3)
        kw["dm"] = 0.05 * rng.standard_normal((2, 3))
    return ref, v, kw
