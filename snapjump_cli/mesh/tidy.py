"""The clean-up of a mesh after gmsh: boundary edges chained in order, unused nodes dropped,
elements oriented counter-clockwise, nodes renumbered in the model's dof order (Cuthill-McKee from
the lower pole, :func:`snapjump_cli.mesh.data.node_order`). Pure numpy functions used by
:func:`snapjump_cli.mesh.build.mesh_scene`.
"""
from __future__ import annotations

import numpy as np

from snapjump_cli.mesh.data import fixed_dofs, jacobian_dets, node_order

__all__ = ["chain_edges", "half_bandwidth", "compact", "orient", "renumber"]

_FLIP = {1: np.array([0, 3, 2, 1]), 2: np.array([0, 3, 2, 1, 7, 6, 5, 4, 8])}


def chain_edges(edges: np.ndarray, start: int) -> np.ndarray:
    """Order and orient the edges of a simple open curve so that it starts at node ``start``."""
    m = edges.shape[0]
    at: dict[int, list[int]] = {}
    for k in range(m):
        at.setdefault(int(edges[k, 0]), []).append(k)
        at.setdefault(int(edges[k, 1]), []).append(k)
    out = np.empty_like(edges)
    used = np.zeros(m, bool)
    node = int(start)
    for i in range(m):
        cand = [k for k in at.get(node, []) if not used[k]]
        if len(cand) != 1:
            raise RuntimeError(f"edge chain broken at node {node} ({len(cand)} continuations)")
        k = cand[0]
        used[k] = True
        e = edges[k].copy()
        if e[0] != node:
            e[0], e[1] = e[1], e[0]
        out[i] = e
        node = int(e[1])
    return out


def half_bandwidth(elements: np.ndarray) -> int:
    return int((elements.max(axis=1) - elements.min(axis=1)).max()) if elements.size else 0


def compact(xy: np.ndarray, elements: np.ndarray, node_sets: dict, edge_sets: dict) -> tuple:
    """Drop the nodes no element uses (gmsh may keep some on points such as centres)."""
    used = np.zeros(xy.shape[0], bool)
    used[elements.ravel()] = True
    if not used.all():
        keep = np.flatnonzero(used)
        remap = np.full(xy.shape[0], -1, np.int64)
        remap[keep] = np.arange(keep.size)
        xy = xy[keep]
        elements = remap[elements]
        edge_sets = {k: remap[v] for k, v in edge_sets.items()}
        node_sets = {k: remap[v] for k, v in node_sets.items()}
    return np.ascontiguousarray(xy), elements, node_sets, edge_sets


def orient(nodes: np.ndarray, elements: np.ndarray, order: int) -> None:
    """Make every element counter-clockwise (positive Jacobian at every Gauss point), in place."""
    det = jacobian_dets(nodes, elements, order)
    neg = (det <= 0).all(axis=1)
    elements[neg] = elements[neg][:, _FLIP[order]]
    if neg.any():
        det = jacobian_dets(nodes, elements, order)
    if not (det > 0).all():
        bad = int(np.flatnonzero((det <= 0).any(axis=1))[0])
        raise RuntimeError(f"element {bad} has a non-positive Jacobian (min {det[bad].min():.3g}): invalid mesh")


def renumber(nodes: np.ndarray, elements: np.ndarray, region: np.ndarray, material: np.ndarray,
              node_sets: dict, edge_sets: dict) -> tuple:
    """Bandwidth reduction: nodes in Cuthill-McKee order from the (inner) cap's lower pole (the
    model's dof order, :func:`~snapjump_cli.mesh.data.node_order`), elements sorted by their
    lowest node."""
    perm = node_order(nodes.shape[0], elements, int(node_sets["pole_lower"][0]),
                      fixed_dofs(nodes.shape[0], node_sets))
    inv = np.empty_like(perm)
    inv[perm] = np.arange(perm.size)
    nodes = nodes[perm]
    elements = inv[elements]
    eorder = np.lexsort((np.arange(elements.shape[0]), elements.min(axis=1)))
    elements, region, material = elements[eorder], region[eorder], material[eorder]
    node_sets = {k: np.sort(inv[v]).astype(np.int64) for k, v in node_sets.items()}
    edge_sets = {k: inv[v].astype(np.int64) for k, v in edge_sets.items()}
    return nodes, elements, region, material, node_sets, edge_sets
