"""Connected components by union-find (blastvox.voxelize.components) against a plain BFS."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blastvox.voxelize.components import component_labels, union_find_labels


def bfs_labels(edges: np.ndarray, n: int) -> np.ndarray:
    """Breadth-first search from each unlabelled node in ascending order."""
    adjacent: list[list[int]] = [[] for _ in range(n)]
    for a, b in edges.tolist():
        adjacent[a].append(b)
        adjacent[b].append(a)
    labels = np.full(n, -1, dtype=np.int64)
    count = 0
    for start in range(n):
        if labels[start] >= 0:
            continue
        labels[start] = count
        queue = deque([start])
        while queue:
            v = queue.popleft()
            for w in adjacent[v]:
                if labels[w] < 0:
                    labels[w] = count
                    queue.append(w)
        count += 1
    return labels


@pytest.mark.parametrize("seed", range(20))
def test_random_graphs_match_breadth_first_search(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    # from nearly all singletons to one giant component
    edges = rng.integers(0, n, size=(int(rng.integers(0, 2 * n)), 2))
    labels = component_labels(edges, n)
    assert labels.dtype == np.int64 and labels.shape == (n,)
    np.testing.assert_array_equal(labels, bfs_labels(edges, n))


@settings(deadline=None, max_examples=200)
@given(st.integers(1, 30).flatmap(lambda n: st.tuples(
    st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)),
                         max_size=40))))
def test_any_small_graph_matches_breadth_first_search(case) -> None:
    n, pairs = case
    edges = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    np.testing.assert_array_equal(component_labels(edges, n), bfs_labels(edges, n))


def test_components_are_numbered_by_their_lowest_node() -> None:
    # components {0, 4}, {1, 2, 5}, {3}; edges deliberately out of order and reversed
    edges = np.array([[5, 2], [4, 0], [2, 1], [1, 1], [2, 5]])
    np.testing.assert_array_equal(component_labels(edges, 6), [0, 1, 1, 2, 0, 1])


def test_a_path_listed_from_its_far_end_is_one_component() -> None:
    n = 1000
    edges = np.stack([np.arange(n - 1, 0, -1), np.arange(n - 2, -1, -1)], axis=1)
    np.testing.assert_array_equal(component_labels(edges, n), np.zeros(n, dtype=np.int64))


def test_no_edges_and_no_nodes() -> None:
    none = np.zeros((0, 2), dtype=np.int64)
    np.testing.assert_array_equal(component_labels(none, 4), [0, 1, 2, 3])
    assert component_labels(none, 0).shape == (0,)
    np.testing.assert_array_equal(union_find_labels(none, 3), [0, 1, 2])


def test_accepts_int32_edges_and_rejects_bad_ones() -> None:
    edges = np.array([[0, 1]], dtype=np.int32)
    np.testing.assert_array_equal(component_labels(edges, 3), [0, 0, 1])
    with pytest.raises(ValueError, match="outside"):
        component_labels(np.array([[0, 3]]), 3)
    with pytest.raises(ValueError, match="outside"):
        component_labels(np.array([[-1, 0]]), 3)
    with pytest.raises(ValueError, match="shape"):
        component_labels(np.array([0, 1]), 3)
    with pytest.raises(ValueError, match="integers"):
        component_labels(np.array([[0.0, 1.0]]), 3)
