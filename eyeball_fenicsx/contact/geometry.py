"""Contact kinematics: a slave point projected on a master surface along its continuous normal.

Segments are the facets as the first-order element sees them (``segments.py``): bilinear
quadrilaterals on hexahedra, linear triangles on tetrahedra, nodes counter-clockwise seen
from outside.

**A continuous normal field.** Every master node a carries the normal

    nu_a = (1 / s_a) sum_(facets f at a) (x_next - x_a) x (x_prev - x_a),

the sum of the corner cross products of the facets around it (the area-weighted average
normal), scaled by s_a, its length in the reference configuration (so nu_a is a unit vector
there and stays close to one). On a segment the normal is interpolated as the position is,
m(xi) = sum_a N_a(xi) nu_a, so it is continuous across segment edges: the surface smoothing
of Abaqus, and the averaged nodal normals of Puso and Laursen (Comput. Methods Appl. Mech.
Engrg. 193 (2004) 601-629).

**Projection.** A slave point x_s lies on the ray from y(xi) = sum_a N_a(xi) x_a along m(xi):

    R(xi, g) = x_s - y(xi) - g m(xi) = 0,

three equations for the surface coordinates xi and g, solved by Newton; the normal distance
is g_n = g |m| (negative: penetration). Both y and m are continuous across segment edges, so
g_n is continuous as the point slides over a fold of the faceted master, and the two
segments at an edge give the same foot there.

**Traction.** The contact pressure p acts along the unit normal n = m / |m| of the foot:
the slave point takes p n, the master nodes -N_a p n. The direction is continuous across
segment edges (the gradient of any gap function is not: its level sets are faceted like the
master), so a node sliding across a fold no longer turns its force there; the price is a
tangent that is not symmetric (as in Puso and Laursen's smoothed mortar contact).

**Linearization.** With q the positions of the slave facet's nodes and of the master nodes
whose normals enter (the segment's patch: its corners and their neighbours along facet
edges), implicit differentiation of R(z(q), q) = 0, z = (xi_1, xi_2, g), gives

    dz/dq = [T_1, T_2, m]^-1 R_q,   T_b = y_,b + g m_,b,
    R_q dq = dx_s - sum_a N_a (dx_a + g dnu_a),

and from it dg_n = |m| dg + g n . dm, dn = (I - n n^T) dm / |m|, dm = m_,b dxi_b + sum_a N_a
dnu_a, dN_a = N_a,b dxi_b, with dnu_a from the cross products (exact: nu_a is quadratic in
the positions). ``project`` returns them; the tests check them against finite differences.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np


def cross(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """a x b of stacks of 3-vectors, their components along ``axis``, by components (np.cross
    without its overhead)."""
    (a0, a1, a2), (b0, b1, b2) = np.moveaxis(a, axis, 0), np.moveaxis(b, axis, 0)
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=axis)


def corner_products(x_seg: np.ndarray) -> np.ndarray:
    """(x_next - x_a) x (x_prev - x_a) at each corner of segments x_seg (m, k, 3)."""
    return cross(np.roll(x_seg, -1, axis=1) - x_seg, np.roll(x_seg, 1, axis=1) - x_seg)


@dataclasses.dataclass
class Patches:
    """Per master segment, the nodes its normal field depends on, and how.

    Attributes:
        nodes: (m, P) node indices of the patch, the segment's corners first; padded with
            the segment's first corner (padded entries carry no incidence).
        next, prev: (m, k, V) for each corner a of the segment, the patch positions of the
            next and previous node of each facet at a (V incidences, padded); ``mask``
            (m, k, V) marks the real ones.
        scale: (m, k) s_a, the reference length of each corner's summed normal.
        mirror: (m, k, 3, 3) the projector applied to each corner's summed normal: the
            identity, or I - e e^T for a node on a symmetry plane of normal e (the facets
            mirrored across it add the opposite e-component); diagonal, the planes being
            coordinate planes.
    """

    nodes: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    mask: np.ndarray
    scale: np.ndarray
    mirror: np.ndarray

    def rows(self, segment: np.ndarray) -> Patches:
        """The patch data of the given segments (one per contact point)."""
        return Patches(self.nodes[segment], self.next[segment], self.prev[segment], self.mask[segment],
                       self.scale[segment], self.mirror[segment])


def patches(segments: np.ndarray, X: np.ndarray, symmetry: Sequence[str] = ()) -> Patches:
    """The ``Patches`` of the surface ``segments`` (m, k) with reference node coordinates X;
    a node's incidences are the facets that hold it (surface-sized, once at setup).
    ``symmetry``: the coordinate axes ("x", "y", "z") whose planes through the origin are
    symmetry planes of the model."""
    m, k = segments.shape
    node_of = segments.ravel()
    order = np.argsort(node_of, kind="stable")
    node_of, facet_of, corner_of = node_of[order], np.repeat(np.arange(m), k)[order], np.tile(np.arange(k), m)[order]
    start = np.searchsorted(node_of, np.arange(len(X)))
    valence = np.searchsorted(node_of, np.arange(len(X)), side="right") - start
    V = int(valence.max(initial=1))
    slot = np.arange(V)
    mask = slot[None, None, :] < valence[segments][:, :, None]  # (m, k, V)
    index = np.minimum(start[segments][:, :, None] + slot, len(node_of) - 1)
    facet, corner = facet_of[index], corner_of[index]
    nxt, prv = segments[facet, (corner + 1) % k], segments[facet, (corner - 1) % k]
    rows = []
    for s in range(m):
        others = np.unique(np.concatenate([nxt[s][mask[s]], prv[s][mask[s]]]))
        rows.append(np.concatenate([segments[s], others[~np.isin(others, segments[s])]]))
    P = max(len(r) for r in rows)
    nodes = np.array([np.pad(r, (0, P - len(r)), constant_values=r[0]) for r in rows])

    def position(values):  # the first match: padded entries repeat the first corner
        return np.argmax(nodes[:, None, None, :] == values[:, :, :, None], axis=-1)

    mirror = np.tile(np.eye(3), (len(X), 1, 1))
    tolerance = 1e-9 * np.abs(X).max(initial=1.0)
    for axis in symmetry:
        k_axis = "xyz".index(axis)
        on_plane = np.abs(X[:, k_axis]) <= tolerance
        mirror[on_plane, k_axis, k_axis] = 0.0
    summed = np.zeros((len(X), 3))
    np.add.at(summed, segments.ravel(), corner_products(X[segments]).reshape(-1, 3))
    summed = np.einsum("nij,nj->ni", mirror, summed)
    return Patches(nodes, position(nxt), position(prv), mask, np.linalg.norm(summed[segments], axis=2),
                   mirror[segments])


def _skew(v):
    """[v]_x (..., 3, 3): [v]_x w = v x w."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], axis=-2)


@dataclasses.dataclass
class Projection:
    """Slave points projected on master segments (arrays over points).

    Attributes:
        g: normal distance g_n (n,), negative when penetrating; xi (n, 2) the foot.
        inside: (n,) the foot lies on the segment and the projection converged.
        normal: n (n, 3) at the foot; N: (n, k) the segment's shape functions there.
        dg, dnormal, dN: derivatives over q = [slave facet nodes, patch nodes] x 3
            components: (n, nq), (n, 3, nq), (n, k, nq); when asked for.
    """

    g: np.ndarray
    xi: np.ndarray
    inside: np.ndarray
    normal: np.ndarray
    N: np.ndarray
    dg: np.ndarray = None
    dnormal: np.ndarray = None
    dN: np.ndarray = None

    def take(self, index: np.ndarray) -> Projection:
        """The projections of some of the points (without derivatives)."""
        return Projection(self.g[index], self.xi[index], self.inside[index], self.normal[index], self.N[index])


def project(x_s: np.ndarray, N_s: np.ndarray, x_p: np.ndarray, patch: Patches | None, kind: type,
            derivatives: bool = False, start: np.ndarray | None = None, iterations: int = 25, tolerance: float = 1e-12,
            nu: np.ndarray | None = None) -> Projection:
    """Project slave points on master segments along the interpolated nodal normal field.

    Args:
        x_s: (n, 3) slave points; N_s: (n, k_s) their weights on their slave facet's nodes.
        x_p: (n, P, 3) positions of the master patch nodes (the segment's corners first; the
            corners suffice when ``nu`` is given and no derivatives are asked).
        patch: ``Patches`` with one row per point (``Patches.rows``); None when ``nu`` is given
            and no derivatives are asked.
        kind: ``Quad`` or ``Triangle`` (the master segment).
        derivatives: also the derivatives over the slave facet's and the patch's nodes.
        start: the feet (n, 2) to start Newton from (default: the segments' centres).
        nu: the corners' normals (n, k, 3) (``corner_normals``), when already known.
    """
    edges = None
    if nu is None or derivatives:
        edges = _patch_edges(x_p, patch, kind.corners)
        nu = _normals(edges, patch)
    x_seg = x_p[:, : kind.corners]
    xi, g, converged = _feet(x_s, nu, x_seg, kind, start, iterations, tolerance)
    if derivatives:
        N, dN, m, m_b, J = _frame(kind, xi, g, nu, x_seg)
    else:
        N = kind.shape(xi)[0]
        m = (N[:, None, :] @ nu)[:, 0]
    length = np.sqrt(_dot(m, m))
    result = Projection(g * length, xi, (kind.outside(xi) < 1e-9) & converged, m / length[:, None], N)
    if derivatives:
        _add_derivatives(result, N_s, x_p.shape[1], patch, edges, g, dN, m_b, J, length)
    return result


def corner_normals(x_p: np.ndarray, patch: Patches, k: int) -> np.ndarray:
    """The normals nu_a (n, k, 3) at the corners of segments with patch nodes at x_p (n, P, 3)."""
    return _normals(_patch_edges(x_p, patch, k), patch)


def _normals(edges, patch):
    e_next, e_prev = edges
    return np.diagonal(patch.mirror, 0, 2, 3) * cross(e_next, e_prev).sum(axis=2) / patch.scale[:, :, None]


def _patch_edges(x_p, patch, k):
    """The edges x_next - x_a and x_prev - x_a (n, k, V, 3) of the facets at each corner a of the
    segments (zero where an incidence is padding)."""
    n, P = x_p.shape[:2]
    flat, first = x_p.reshape(n * P, 3), (np.arange(n) * P)[:, None, None]
    corner, mask = x_p[:, :k, None], patch.mask[..., None]
    e_next = np.where(mask, flat.take(first + patch.next, axis=0) - corner, 0.0)
    e_prev = np.where(mask, flat.take(first + patch.prev, axis=0) - corner, 0.0)
    return e_next, e_prev


def _dot(a, b, axis=-1):
    return (a * b).sum(axis=axis)


def _frame(kind, xi, g, nu, x_seg):
    """N, dN, the normal field m and its derivatives m_b at the feet xi, and the Jacobian
    [T_1, T_2, m] of the projection's residual over (xi, g)."""
    N, dN = kind.shape(xi)
    dN_t = dN.transpose(0, 2, 1)
    m, m_b = (N[:, None, :] @ nu)[:, 0], dN_t @ nu  # batched products: several times faster than einsum here
    T = dN_t @ x_seg + g[:, None, None] * m_b
    return N, dN, m, m_b, np.stack([T[:, 0], T[:, 1], m], axis=2)  # columns T_1, T_2, m


def _solve3(c0, c1, c2, r):
    """x (3, n) with [c0, c1, c2] x = r for a stack of 3 x 3 systems given by their columns (3, n),
    by Cramer's rule (several times faster than LAPACK on so small systems)."""
    c12 = cross(c1, c2, 0)
    return np.stack([_dot(r, c12, 0), _dot(c0, cross(r, c2, 0), 0), _dot(c0, cross(c1, r, 0), 0)]) / _dot(c0, c12, 0)


def _polynomial(c, a, b):
    """y = sum_a N_a(xi) v_a and its derivatives y_,1, y_,2 (w, n) at xi = (a, b), from the
    coefficients c (terms, w, n) of the shape functions' polynomial (``segments.py``)."""
    y, y_1, y_2 = c[0] + a * c[1] + b * c[2], c[1], c[2]
    if len(c) == 4:  # the bilinear term
        y, y_1, y_2 = y + (a * b) * c[3], y_1 + b * c[3], y_2 + a * c[3]
    return y, y_1, y_2


def _feet(x_s, nu, x_seg, kind, start, iterations, tolerance):
    """Newton on R(xi, g) = x_s - y(xi) - g m(xi) = 0 from ``start`` (default: the segments'
    centres): the feet xi (n, 2), g (n,) and whether each converged (n,). A point whose foot
    is clipped to the segment's bounds is far outside it, and stops there. y and m, with their
    derivatives, are the polynomials in xi of the shape functions, over the points still moving
    (arrays by component first: contiguous rows)."""
    n, (lo, hi) = len(x_s), kind.bounds
    size = np.sqrt(np.linalg.norm(cross(x_seg[:, 2] - x_seg[:, 0], x_seg[:, -1] - x_seg[:, 1]), axis=1))
    c = np.tensordot(kind.polynomial, np.concatenate([x_seg, nu], axis=2).transpose(1, 2, 0), axes=(1, 0))
    xi = np.tile(np.asarray(kind.centre, dtype=float), (n, 1)) if start is None else start.copy()
    a, b, xs = xi[:, 0].copy(), xi[:, 1].copy(), np.ascontiguousarray(x_s.T)
    f = _polynomial(c, a, b)[0]
    g = _dot(xs - f[:3], f[3:], 0) / _dot(f[3:], f[3:], 0)
    converged, moving, g_out = np.zeros(n, dtype=bool), np.arange(n), g.copy()
    for _ in range(iterations):
        if not len(moving):
            break
        f, f_1, f_2 = _polynomial(c, a, b)
        m = f[3:]
        step = _solve3(f_1[:3] + g * f_1[3:], f_2[:3] + g * f_2[3:], m, xs - f[:3] - g * m)
        trial_a, trial_b = a + step[0], b + step[1]
        a, b, g = np.clip(trial_a, lo, hi), np.clip(trial_b, lo, hi), g + step[2]
        small = (np.maximum(np.abs(step[0]), np.abs(step[1])) < tolerance) & (np.abs(step[2]) < tolerance * size)
        done = small | (trial_a != a) | (trial_b != b)  # clipped: far outside the segment, no contact with it
        if done.any():
            converged[moving[small]] = True
            index, keep = moving[done], ~done
            xi[index, 0], xi[index, 1], g_out[index] = a[done], b[done], g[done]
            moving, a, b, g, size = moving[keep], a[keep], b[keep], g[keep], size[keep]
            c, xs = c[..., keep], xs[:, keep]
    xi[moving, 0], xi[moving, 1], g_out[moving] = a, b, g
    return xi, g_out, converged


def _add_derivatives(result, N_s, P, patch, edges, g, dN, m_b, J, length):
    """Set the derivatives dg, dnormal, dN of ``result`` over q = [slave facet nodes, patch nodes]
    (the module docstring's linearization), from the edges at the segments' corners and the
    frame at the feet."""
    (n, k), k_s = result.N.shape, N_s.shape[1]
    N, normal = result.N, result.normal
    eye3, nq = np.eye(3), 3 * (k_s + P)
    Rq = np.zeros((n, 3, nq))
    Rq[:, :, : 3 * k_s] = (N_s[:, None, :, None] * eye3[None, :, None, :]).reshape(n, 3, 3 * k_s)
    Rq[:, :, 3 * k_s: 3 * (k_s + k)] = -(N[:, None, :, None] * eye3[None, :, None, :]).reshape(n, 3, 3 * k)
    dM = _normal_derivative(N, P, patch, edges)
    Rq[:, :, 3 * k_s:] -= g[:, None, None] * dM
    dz = np.linalg.solve(J, Rq)  # (n, 3, nq): dxi_1, dxi_2, dg
    dm = np.einsum("nbi,nbq->niq", m_b, dz[:, :2])
    dm[:, :, 3 * k_s:] += dM
    result.dg = length[:, None] * dz[:, 2] + g[:, None] * np.einsum("ni,niq->nq", normal, dm)
    projector = eye3 - normal[:, :, None] * normal[:, None, :]
    result.dnormal = np.einsum("nij,njq->niq", projector, dm) / length[:, None, None]
    result.dN = np.einsum("nab,nbq->naq", dN, dz[:, :2])


def _normal_derivative(N, P, patch, edges):
    """sum_a N_a dnu_a / dq over the patch nodes (n, 3, 3P), with
    d[e_n x e_p] = -[e_p]_x (dx_next - dx_a) + [e_n]_x (dx_prev - dx_a)."""
    n, k = N.shape
    skew_next, skew_prev = _skew(edges[0]), _skew(edges[1])  # (n, k, V, 3, 3)
    weight = (N[:, :, None] * patch.mask / patch.scale[:, :, None])[..., None, None]
    weight = weight * np.diagonal(patch.mirror, 0, 2, 3)[:, :, None, :, None]  # the mirror, on the rows
    dM = np.zeros((n, P, 9))
    dM[:, :k] = (weight * (skew_prev - skew_next)).sum(axis=2).reshape(n, k, 9)  # the corners themselves
    index = (np.arange(n) * P)[:, None, None] + np.concatenate([patch.next, patch.prev], axis=2)
    blocks = np.concatenate([-weight * skew_prev, weight * skew_next], axis=2).reshape(-1, 9)
    for c in range(9):  # the neighbours along each facet, summed by bincount
        dM[:, :, c] += np.bincount(index.ravel(), weights=blocks[:, c], minlength=n * P).reshape(n, P)
    return dM.reshape(n, P, 3, 3).transpose(0, 2, 1, 3).reshape(n, 3, 3 * P)


def traction(weight: np.ndarray, pressure: np.ndarray, stiffness: np.ndarray, proj: Projection, N_s: np.ndarray,
             patch_size: int, tangent: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Residual and (with ``tangent``) tangent of a contact pressure p(g_n) acting along the
    normal n at the foot.

    The slave point takes p n, the master segment's corners -N_a p n; with the residual as
    internal minus external force,

        r = -W p Gamma,  Gamma = [N_s,i n (slave nodes), -N_a n (corners), 0 (other patch nodes)],
        K = dr/dq = W k Gamma dg_n^T - W p dGamma/dq,   k = -dp/dg_n,

    for points of area weight W (n,), pressure p (n,) and stiffness k (n,), on patches of
    ``patch_size`` nodes. Returns r (n, nq) and K (n, nq, nq) (None without ``tangent``: then
    ``proj`` needs no derivatives), in the order of ``project``'s q.
    """
    n, k_s, k = len(weight), N_s.shape[1], proj.N.shape[1]
    nq = 3 * (k_s + patch_size)
    n_vec = proj.normal
    gamma = np.zeros((n, nq))
    gamma[:, : 3 * k_s] = (N_s[:, :, None] * n_vec[:, None, :]).reshape(n, 3 * k_s)
    gamma[:, 3 * k_s: 3 * (k_s + k)] = -(proj.N[:, :, None] * n_vec[:, None, :]).reshape(n, 3 * k)
    r = -(weight * pressure)[:, None] * gamma
    if not tangent:
        return r, None
    dgamma = np.zeros((n, nq, nq))
    dgamma[:, : 3 * k_s] = (N_s[:, :, None, None] * proj.dnormal[:, None, :, :]).reshape(n, 3 * k_s, nq)
    dgamma[:, 3 * k_s: 3 * (k_s + k)] = -(proj.N[:, :, None, None] * proj.dnormal[:, None, :, :]
                                          + n_vec[:, None, :, None] * proj.dN[:, :, None, :]).reshape(n, 3 * k, nq)
    K = (weight * stiffness)[:, None, None] * gamma[:, :, None] * proj.dg[:, None, :] \
        - (weight * pressure)[:, None, None] * dgamma
    return r, K
