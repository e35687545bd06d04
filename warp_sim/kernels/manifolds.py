"""Contact manifolds and their colouring, for a Gauss-Seidel solve that runs one thread per manifold.

A manifold is the contacts of one candidate pair (a box on the ground: its four corners). The
contacts are sorted by pair (``count_pair_contacts``, a scan, ``sort_by_pair``), so manifold p
owns rows ``offsets[p] .. offsets[p] + counts[p]``. The manifolds are then coloured so that
no two of one colour share a body (``colour_pairs``: greedy first fit, each body's used colours
a bit mask claimed with compare-and-swap, so threads that race for a colour never both get it).
A static side (a collider or a plane, never moved by the solve) takes no colour, and the
manifolds against statics are coloured apart from the body-body ones, so a solve can run them
last. Solving one colour at a time, one thread per manifold, is exactly a sequential
Gauss-Seidel sweep in colour order; on the CPU (threads run in order) the colouring and the
order are deterministic.

Private: every kernel here is for the simulator's own use (the body contact pass); their
arguments may change between releases. ``__all__`` is empty.
"""
import warp as wp

from .detection import ContactBuffer, beyond, is_body

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

#: colours per class and round: bits of ``WORDS`` int32 masks per body and class
WORDS = wp.constant(2)
COLOURS = wp.constant(64)
UNCOLOURED = wp.constant(-2)


@wp.struct
class ManifoldSet:
    """The manifolds of a step: pair p owns rows offsets[p] .. offsets[p] + counts[p]; row_ids: each row's
    bodies in the order its normal refers to (the narrow phase may write a pair either way round); order lists
    the manifolds colour by colour: colour k's sizes[k] manifolds from order[starts[k]] on (the launch for colour k
    runs at least that many threads; the rest exit)."""

    row_ids: wp.array(dtype=wp.vec2i)
    offsets: wp.array(dtype=wp.int32)
    counts: wp.array(dtype=wp.int32)
    order: wp.array(dtype=wp.int32)
    quiet: wp.array(dtype=wp.int32)          # per pair: 1 once a resting sweep left it converged
    starts: wp.array(dtype=wp.int32)         # per colour: its first place in order
    sizes: wp.array(dtype=wp.int32)          # per colour: its manifolds
    body_count: int


@wp.func
def manifold_rows(m: ManifoldSet, colour: int, thread: int):
    """(its pair, its first row, one past its last row) of the colour's manifold number ``thread``; the pair is
    -1 past the colour's size (a captured launch runs more threads than the colour has). A negative ``colour``
    is a run of consecutive colours from place -1 - colour of ``order`` on, launched as one with exactly their
    manifolds' count of threads (on the CPU, whose launch runs its threads in order, the same sweep as a launch
    per colour: passes.body_contacts)."""
    place = -1 - colour + thread
    if colour >= 0:
        if thread >= m.sizes[colour]:
            return -1, 0, 0
        place = m.starts[colour] + thread
    p = m.order[place]
    start = m.offsets[p]
    return p, start, start + m.counts[p]


@wp.func
def untouched(m: ManifoldSet, stamp: wp.array(dtype=wp.int32), row: int, sweep: int):
    """Whether no impulse changed the bodies of the manifold holding ``row`` since the sweep before ``sweep``
    (stamp: per body, the last sweep that changed it)."""
    i = m.row_ids[row][0]
    j = m.row_ids[row][1]
    quiet = stamp[i] < sweep - 1
    if is_body(j, m.body_count):
        quiet = quiet and stamp[j] < sweep - 1
    return quiet


@wp.func
def touch(m: ManifoldSet, stamp: wp.array(dtype=wp.int32), row: int, sweep: int):
    """Mark the bodies of the manifold holding ``row`` as changed in ``sweep``."""
    stamp[m.row_ids[row][0]] = sweep
    if is_body(m.row_ids[row][1], m.body_count):
        stamp[m.row_ids[row][1]] = sweep


@wp.kernel
def count_pair_contacts(contact_pair: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
                        counts: wp.array(dtype=wp.int32)):
    """counts[p]: the contacts of candidate pair p (zeroed beforehand); count[0]: the contacts found."""
    c = wp.tid()
    if beyond(count, c, contact_pair.shape[0]):
        return
    wp.atomic_add(counts, contact_pair[c], 1)


@wp.kernel
def sort_by_pair(contact_pair: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
                 offsets: wp.array(dtype=wp.int32), cursor: wp.array(dtype=wp.int32), slot: wp.array(dtype=wp.int32)):
    """slot[c]: contact c's row, its pair's rows being offsets[p] (an exclusive scan of the counts) onward."""
    c = wp.tid()
    if beyond(count, c, contact_pair.shape[0]):
        return
    p = contact_pair[c]
    slot[c] = offsets[p] + wp.atomic_add(cursor, p, 1)


@wp.func
def claim(masks: wp.array(dtype=wp.int32), word: int, bit: int):
    """Set ``bit`` of masks[word] if it is clear; whether this call set it."""
    old = masks[word]
    claimed = int(0)
    while (old & bit) == 0 and claimed == 0:
        seen = wp.atomic_cas(masks, word, old, old | bit)
        if seen == old:
            claimed = 1
        else:
            old = seen
    return claimed == 1


@wp.func
def release(masks: wp.array(dtype=wp.int32), word: int, bit: int):
    """Clear ``bit`` of masks[word] (set by this thread)."""
    old = masks[word]
    done = int(0)
    while done == 0:
        seen = wp.atomic_cas(masks, word, old, old & ~bit)
        if seen == old:
            done = 1
        else:
            old = seen


@wp.kernel
def colour_pairs(ids: wp.array(dtype=wp.vec2i), counts: wp.array(dtype=wp.int32), body_count: int, round_base: int,
                 masks: wp.array(dtype=wp.int32), colour: wp.array(dtype=wp.int32),
                 sizes: wp.array(dtype=wp.int32), overflow: wp.array(dtype=wp.int32)):
    """Give each uncoloured manifold p (colour[p] == UNCOLOURED; -1 for a pair without contacts) the first colour
    free on both its bodies: body-body manifolds take colours round_base + k, manifolds against a static side
    round_base + COLOURS + k (k < COLOURS); masks: per body and class WORDS words of used colours (zeroed per
    round); sizes[colour]: manifolds per colour; overflow[0]: manifolds left for another round."""
    p = wp.tid()
    if counts[p] == 0:
        colour[p] = -1
        return
    if colour[p] != UNCOLOURED:
        return
    i = ids[p][0]
    j = ids[p][1]
    dynamic = is_body(j, body_count)
    cls = 1
    if dynamic:
        cls = 0
    for k in range(COLOURS):
        word = k // 32
        bit = int(1) << (k % 32)
        if claim(masks, (2 * i + cls) * WORDS + word, bit):
            if not dynamic:
                colour[p] = round_base + COLOURS + k
                wp.atomic_add(sizes, colour[p], 1)
                return
            if claim(masks, (2 * j + cls) * WORDS + word, bit):
                colour[p] = round_base + k
                wp.atomic_add(sizes, colour[p], 1)
                return
            release(masks, (2 * i + cls) * WORDS + word, bit)
    wp.atomic_add(overflow, 0, 1)


@wp.kernel
def order_by_colour(colour: wp.array(dtype=wp.int32), starts: wp.array(dtype=wp.int32),
                    cursor: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32)):
    """order: the manifolds grouped by colour, colour k's from starts[k] on."""
    p = wp.tid()
    k = colour[p]
    if k >= 0:
        order[starts[k] + wp.atomic_add(cursor, k, 1)] = p


@wp.kernel
def sizes_in_order(sizes: wp.array(dtype=wp.int32), solve_order: wp.array(dtype=wp.int32),
                   ordered: wp.array(dtype=wp.int32)):
    """ordered[k]: the size of the colour solved k-th (solve_order[k]), for the scan that places the colours."""
    k = wp.tid()
    ordered[k] = sizes[solve_order[k]]


@wp.kernel
def place_colours(solve_order: wp.array(dtype=wp.int32), firsts: wp.array(dtype=wp.int32),
                  starts: wp.array(dtype=wp.int32)):
    """starts[colour]: its first place in the order (firsts: the exclusive scan of the sizes in solve order)."""
    k = wp.tid()
    starts[solve_order[k]] = firsts[k]


@wp.kernel
def check_colours(sizes: wp.array(dtype=wp.int32), threads: wp.array(dtype=wp.int32),
                  flags: wp.array(dtype=wp.int32)):
    """A captured step: flags[0] counts the colours with more manifolds than their recorded launches have threads
    (threads[k]; 0 for a colour the recording did not launch)."""
    k = wp.tid()
    if sizes[k] > threads[k]:
        wp.atomic_add(flags, 0, 1)


@wp.kernel
def gate_response(pairs: ContactBuffer, contacts: ContactBuffer, pair_threads: int, contact_threads: int,
                  left: wp.array(dtype=wp.int32), impacts: wp.array(dtype=wp.int32), flags: wp.array(dtype=wp.int32)):
    """A captured step's gates, one thread: flags[0] (the colours too large, from check_colours) becomes 1 if the
    recorded launches missed anything (more pairs or contacts than their threads, which are at most the buffers'
    capacities; manifolds left uncoloured after the recorded rounds; a colour too large), else 0; flags[1]:
    respond (nothing missed, some contact); flags[2]: collide (respond, and an impact); flags[3]: keep (nothing
    missed: the warm start may be rewritten)."""
    missed = flags[0] > 0 or pairs.count[0] > pair_threads or contacts.count[0] > contact_threads
    missed = missed or left[0] > 0
    respond = not missed and contacts.count[0] > 0
    flags[0] = wp.where(missed, 1, 0)
    flags[1] = wp.where(respond, 1, 0)
    flags[2] = wp.where(respond and impacts[0] > 0, 1, 0)
    flags[3] = wp.where(missed, 0, 1)
