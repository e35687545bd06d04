"""A step's contacts grouped into manifolds (one per pair) and the manifolds coloured for a parallel solve.

See ``kernels.manifolds``: the rows of one manifold are consecutive, and no two manifolds of one
colour share a body, so a Gauss-Seidel sweep is one launch per colour with one thread per manifold.
Body-body colours come first, then the colours of manifolds against static colliders and planes
(a solve that ends on them leaves the ground's constraints the last word).
"""
from __future__ import annotations

import functools

import numpy as np
import warp as wp

from ..core.model import Model
from ..kernels import manifolds as manifold_kernels
from .detector import Detection

ROUND = 2 * manifold_kernels.COLOURS   # colours of one colouring round, body-body then static


@functools.cache
def solve_order(rounds: int) -> np.ndarray:
    """The colour indices of ``rounds`` colouring rounds in solve order: every round's body-body colours, then
    every round's static ones."""
    colours = manifold_kernels.COLOURS
    base = np.arange(rounds)[:, None] * ROUND + np.arange(colours)
    return np.concatenate([base.ravel(), (base + colours).ravel()])


class ContactManifolds:
    """Manifolds and colours of a Detection's last contacts (``sort``, then ``colour``).

    slot: each contact's row (contacts sorted by pair); row_ids: each row's bodies; set: the kernels'
    ManifoldSet (row_ids, offsets, counts, order, body_count); colours_of: each pair's colour (-1: no
    contacts); colours: (first, size) per colour in solve order, body-body ones first; body_colours: how
    many of them are body-body; rounds: colouring rounds of the last colouring (1 unless a body touched more
    than 64 others); tally: the colours' sizes, then the overflow and impact counters
    """

    def __init__(self, model: Model, detection: Detection):
        self.model = model
        self.detection = detection
        self.masks = model.zeros(max(1, model.body_count) * 2 * manifold_kernels.WORDS, wp.int32)
        self.overflow = model.zeros(1, wp.int32)
        self._pair_capacity = self._contact_capacity = self._colour_capacity = 0
        self.set = None
        self.colours: list[tuple[int, int]] = []
        self.body_colours = 0
        self.rounds = 0

    def _ensure(self) -> None:
        """Arrays for the detection's current capacities (they only grow; a new ManifoldSet when they do)."""
        m, d = self.model, self.detection
        grown = False
        if d.pairs.capacity > self._pair_capacity:
            P = self._pair_capacity = d.pairs.capacity
            self.counts, self.offsets, self.cursor = (m.zeros(P, wp.int32) for _ in range(3))
            self.colours_of, self.order = m.zeros(P, wp.int32), m.zeros(P, wp.int32)
            self.quiet = m.zeros(P, wp.int32)
            grown = True
        if d.contacts.capacity > self._contact_capacity:
            C = self._contact_capacity = d.contacts.capacity
            self.slot, self.row_ids = m.zeros(C, wp.int32), m.zeros(C, wp.vec2i)
            grown = True
        if grown:
            self.set = manifold_kernels.ManifoldSet()
            self.set.row_ids, self.set.offsets, self.set.counts = self.row_ids, self.offsets, self.counts
            self.set.order, self.set.quiet, self.set.body_count = self.order, self.quiet, m.body_count
        if self._colour_capacity < ROUND:
            self._allocate_colours(ROUND)

    def _allocate_colours(self, capacity: int) -> None:
        """Per-colour arrays for ``capacity`` colours; ``tally`` ends with two counters, viewed as ``overflow``
        (manifolds left for another colouring round) and ``impacts`` (contacts the response marks as impacts),
        so one read-back gives them all."""
        self._colour_capacity = capacity
        self.tally = self.model.zeros(capacity + 2, wp.int32)
        self.sizes, self.overflow, self.impacts = self.tally[:capacity], self.tally[capacity:capacity + 1], \
            self.tally[capacity + 1:]
        self.starts = self.model.zeros(capacity, wp.int32)
        self.colour_cursor = self.model.zeros(capacity, wp.int32)

    def sort(self) -> None:
        """Sort the detection's contacts by pair: ``slot`` gives each contact's row; zeroes ``impacts``."""
        m, d = self.model, self.detection
        self._ensure()
        contact_pair = d.contacts.buffer.pair
        self.counts.zero_()
        m.launch(manifold_kernels.count_pair_contacts, d.count, [contact_pair, self.counts])
        wp.utils.array_scan(self.counts, self.offsets, inclusive=False)
        self.cursor.zero_()
        m.launch(manifold_kernels.sort_by_pair, d.count, [contact_pair, self.offsets, self.cursor, self.slot])
        self.tally.zero_()
        self.quiet.zero_()   # every manifold is solved in the first resting sweep

    def colour(self) -> tuple[list[tuple[int, int]], int]:
        """Colour the pairs (after ``sort``); returns ``colours`` and the count in ``impacts``."""
        m, d = self.model, self.detection
        pairs = d.pair_count
        self.colours_of.fill_(manifold_kernels.UNCOLOURED)
        self.rounds = 0
        while True:
            base = self.rounds * ROUND
            if base + ROUND > self._colour_capacity:
                tally = self.tally.numpy()
                self._allocate_colours(2 * self._colour_capacity)
                grown = np.zeros(self._colour_capacity + 2, np.int32)
                grown[:tally.size - 2], grown[-1] = tally[:-2], tally[-1]
                self.tally.assign(grown)
            self.masks.zero_()
            self.overflow.zero_()
            m.launch(manifold_kernels.colour_pairs, pairs, [d.pairs.buffer.ids, self.counts, m.body_count, base,
                                                           self.masks, self.colours_of, self.sizes, self.overflow])
            self.rounds += 1
            tally = self.tally.numpy()
            if tally[-2] == 0:
                break
        index = solve_order(self.rounds)
        order = tally[index]                    # sizes in solve order: body-body colours of every round, then static
        firsts = np.cumsum(order) - order
        starts = np.zeros(self._colour_capacity, np.int32)
        starts[index] = firsts
        self.starts.assign(starts)
        self.colour_cursor.zero_()
        m.launch(manifold_kernels.order_by_colour, pairs, [self.colours_of, self.starts, self.colour_cursor,
                                                          self.order])
        used = np.flatnonzero(order)
        self.body_colours = int(np.count_nonzero(used < self.rounds * manifold_kernels.COLOURS))
        self.colours = list(zip(firsts[used].tolist(), order[used].tolist()))
        return self.colours, int(tally[-1])
