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
from .buffers import launch_threads
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
    ManifoldSet (row_ids, offsets, counts, order, quiet, starts, sizes, body_count); colours_of: each pair's colour
    (-1: no contacts); colours: (colour, its manifolds) per colour launched, in solve order, body-body ones first;
    body_colours: how many of them are body-body; rounds: colouring rounds of the last colouring (1 unless a body
    touched more than 64 others); tally: the colours' sizes, then the overflow and impact counters; flags: a
    captured step's gates (kernels.manifolds.gate_response)
    """

    spare_colours = 1   # a captured step launches this many unused colours of each class too

    def __init__(self, model: Model, detection: Detection):
        self.model = model
        self.detection = detection
        self.masks = model.zeros(max(1, model.body_count) * 2 * manifold_kernels.WORDS, wp.int32)
        self.flags = model.zeros(4, wp.int32)
        self.missed, self.respond, self.collide, self.keep = (self.flags[k:k + 1] for k in range(4))
        self._pair_capacity = self._contact_capacity = self._colour_capacity = 0
        self._orders: dict[int, tuple] = {}
        self._captured: list[tuple[int, int]] | None = None
        self._captured_body_colours = 0
        self.set = None
        self.colours: list[tuple[int, int]] = []
        self.body_colours = 0
        self.rounds = 1

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
        if self._colour_capacity < ROUND:
            self._allocate_colours(ROUND)
            grown = True
        if grown or self.set is None:
            self.set = manifold_kernels.ManifoldSet()
            self.set.row_ids, self.set.offsets, self.set.counts = self.row_ids, self.offsets, self.counts
            self.set.order, self.set.quiet, self.set.body_count = self.order, self.quiet, m.body_count
            self.set.starts, self.set.sizes = self.starts, self.sizes

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
        self.threads = self.model.zeros(capacity, wp.int32)
        self._orders.clear()
        self.set = None

    @property
    def colour_capacity(self) -> int:
        """Colours the per-colour arrays hold (they grow with the colouring rounds)."""
        return self._colour_capacity

    def _order(self, rounds: int) -> tuple:
        """(solve order, the sizes in it, their exclusive scan) on the device for ``rounds`` rounds."""
        if rounds not in self._orders:
            m = self.model
            order = solve_order(rounds)
            self._orders[rounds] = (wp.array(order.astype(np.int32), dtype=wp.int32, device=m.device),
                                    m.zeros(order.size, wp.int32), m.zeros(order.size, wp.int32))
        return self._orders[rounds]

    def sort(self) -> None:
        """Sort the detection's contacts by pair: ``slot`` gives each contact's row; zeroes ``impacts``."""
        m, d = self.model, self.detection
        self._ensure()
        contact_pair, found = d.contacts.buffer.pair, d.contacts.count
        contacts = d.threads()[1]
        self.counts.zero_()
        m.launch(manifold_kernels.count_pair_contacts, contacts, [contact_pair, found, self.counts])
        wp.utils.array_scan(self.counts, self.offsets, inclusive=False)
        self.cursor.zero_()
        m.launch(manifold_kernels.sort_by_pair, contacts, [contact_pair, found, self.offsets, self.cursor, self.slot])
        self.tally.zero_()
        self.quiet.zero_()   # every manifold is solved in the first resting sweep

    def colour(self) -> tuple[list[tuple[int, int]], int, int | None]:
        """Colour the pairs (after ``sort``) and order the manifolds by colour; returns ``colours``,
        ``body_colours`` and the count in ``impacts``. While a step is captured nothing is read back: the rounds
        are those of the last uncaptured colouring and the launches its colours (before_capture), the
        count is None, and ``flags`` say after the replay whether the launches missed anything (then the step
        is done again, uncaptured)."""
        m, d = self.model, self.detection
        capturing = m.launcher.capturing
        pairs = d.threads()[0]
        self.colours_of.fill_(manifold_kernels.UNCOLOURED)
        rounds = 0
        while True:
            base = rounds * ROUND
            if base + ROUND > self._colour_capacity:   # uncaptured only: the captured rounds fit
                tally = self.tally.numpy()
                self._allocate_colours(2 * self._colour_capacity)
                self._ensure()
                grown = np.zeros(self._colour_capacity + 2, np.int32)
                grown[:tally.size - 2], grown[-1] = tally[:-2], tally[-1]
                self.tally.assign(grown)
            self.masks.zero_()
            self.overflow.zero_()
            m.launch(manifold_kernels.colour_pairs, pairs, [d.pairs.buffer.ids, self.counts, m.body_count, base,
                                                           self.masks, self.colours_of, self.sizes, self.overflow])
            rounds += 1
            if capturing:
                if rounds == self.rounds:
                    break
                continue
            tally = self.tally.numpy()
            if tally[-2] == 0:
                break
        order, ordered, firsts = self._order(rounds)
        m.launch(manifold_kernels.sizes_in_order, order.size, [self.sizes, order, ordered])
        wp.utils.array_scan(ordered, firsts, inclusive=False)
        m.launch(manifold_kernels.place_colours, order.size, [order, firsts, self.starts])
        self.colour_cursor.zero_()
        m.launch(manifold_kernels.order_by_colour, pairs, [self.colours_of, self.starts, self.colour_cursor,
                                                          self.order])
        if capturing:
            self.flags.zero_()
            m.launch(manifold_kernels.check_colours, self._colour_capacity, [self.sizes, self.threads, self.flags])
            m.launch(manifold_kernels.gate_response, 1, [d.pairs.buffer, d.contacts.buffer, *d.captured,
                                                        self.overflow, self.impacts, self.flags])
            return self._captured, self._captured_body_colours, None
        self.rounds = rounds
        index = solve_order(rounds)
        sizes = tally[index]
        used = np.flatnonzero(sizes)
        self.body_colours = int(np.count_nonzero(used < rounds * manifold_kernels.COLOURS))
        self.colours = list(zip(index[used].tolist(), sizes[used].tolist()))
        self._captured = None   # a captured step after this one launches for this colouring
        return self.colours, self.body_colours, int(tally[-1])

    def before_capture(self) -> bool:
        """Before a step is recorded (outside the capture, which must not allocate or copy from the host): the
        arrays for the capacities and the solve order of the rounds, and a captured step's colours: those of the
        last uncaptured colouring and ``spare_colours`` more, with their threads (buffers.launch_threads), and
        ``threads``, their thread counts by colour (for check_colours). Returns True where these are new (graphs
        recorded before read ``threads`` for other launches: they must be dropped)."""
        self._ensure()
        self._order(self.rounds)
        if self._captured is not None:
            return False
        body, static = list(self.colours[:self.body_colours]), list(self.colours[self.body_colours:])
        colours = manifold_kernels.COLOURS
        top = (self.rounds - 1) * ROUND
        for group, first in ((body, top), (static, top + colours)):
            used = {k for k, _ in group}
            group += [(k, 0) for k in range(first, first + colours) if k not in used][:self.spare_colours]
        position = {int(k): i for i, k in enumerate(solve_order(self.rounds))}
        launches = sorted(body + static, key=lambda c: position[c[0]])
        self._captured = [(k, launch_threads(n)) for k, n in launches]
        self._captured_body_colours = len(body)
        threads = np.zeros(self._colour_capacity, np.int32)
        for k, n in self._captured:
            threads[k] = n
        self.threads.assign(threads)
        return True
