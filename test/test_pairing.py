"""PairMatcher: exact and approximate stamp matching of two inputs, ordering and accounting.

One sample at a time (:meth:`add`) and vectorised in batches (:meth:`add_batch`), which must
agree on pairs, counters and queues."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from tcomp_core.online.pairing import PairCounters, PairMatcher, Pairs

T0 = 1_700_000_000 * 1_000_000_000  # a realistic epoch stamp, ns
MS = 1_000_000  # ns


class ReferenceMatcher:
    """Brute-force restatement of the rules (dicts and min(), no bisection) to compare against."""

    def __init__(self, slop_ns, queue_size):
        self.slop = slop_ns
        self.queue_size = queue_size
        self.queues = [{}, {}]
        self.last = [None, None]
        self.received = [0, 0]
        self.unmatched = [0, 0]
        self.matched = self.duplicates = self.out_of_order = 0

    def add(self, index, stamp, value):
        self.received[index] += 1
        own, other = self.queues[index], self.queues[1 - index]
        if self.last[index] is not None and stamp <= self.last[index]:
            self.out_of_order += 1
            return []
        if stamp in own:
            self.duplicates += 1
            return []
        own[stamp] = value
        candidates = [s for s in other if abs(s - stamp) <= self.slop]
        if candidates:
            partner = min(candidates, key=lambda s: (abs(s - stamp), s))
            own_value, other_value = own.pop(stamp), other.pop(partner)
            self.last[index], self.last[1 - index] = stamp, partner
            for side, queue, limit in ((index, own, stamp), (1 - index, other, partner)):
                for s in [s for s in queue if s < limit]:
                    del queue[s]
                    self.unmatched[side] += 1
            self.matched += 1
            if index == 0:
                return [(stamp, own_value, other_value)]
            return [(partner, other_value, own_value)]
        if len(own) > self.queue_size:
            del own[min(own)]
            self.unmatched[index] += 1
        return []

    def counters(self):
        return {
            "received_tc1": self.received[0],
            "received_tc2": self.received[1],
            "matched": self.matched,
            "unmatched_tc1": self.unmatched[0],
            "unmatched_tc2": self.unmatched[1],
            "out_of_order": self.out_of_order,
            "duplicates": self.duplicates,
            "invalid_tc1": 0,
            "invalid_tc2": 0,
            "malformed_tc1": 0,
            "malformed_tc2": 0,
            "discontinuities": 0,
        }


def feed(matcher, events):
    """Offer (index, stamp, value) events one by one; return every pair emitted, in order."""
    pairs = []
    for index, stamp, value in events:
        pairs.extend(matcher.add(index, stamp, value))
    return pairs


def check_identity(matcher):
    c = matcher.counters
    total = sum(c.received)
    dropped = sum(c.unmatched) + c.duplicates + c.out_of_order + sum(c.invalid)
    assert total == 2 * c.matched + dropped + sum(matcher.pending())


def stream(index, stamps):
    """Events of one input whose value encodes input and position: 1000 * index + position."""
    return [(index, int(s), float(1000 * index + k)) for k, s in enumerate(stamps)]


def merge_bursts(first, second, rng, max_burst):
    """Interleave two event lists in bursts of random length, each list keeping its order."""
    out, i, j, turn = [], 0, 0, 0
    while i < len(first) or j < len(second):
        n = int(rng.integers(1, max_burst + 1))
        if turn == 0:
            out += first[i : i + n]
            i += n
        else:
            out += second[j : j + n]
            j += n
        turn ^= 1
    return out


# -- exact matching -----------------------------------------------------------------------------
@pytest.mark.parametrize("order", ["tc1_first", "tc2_first", "alternate", "bursts", "random"])
def test_exact_stamps_pair_in_any_interleaving(order):
    rng = np.random.default_rng(11)
    n = 200
    stamps = T0 + np.arange(n) * 2 * MS
    tc1, tc2 = stream(0, stamps), stream(1, stamps)
    if order == "tc1_first":
        events = tc1 + tc2
    elif order == "tc2_first":
        events = tc2 + tc1
    elif order == "alternate":
        events = [e for pair in zip(tc1, tc2, strict=True) for e in pair]
    elif order == "bursts":
        events = merge_bursts(tc1, tc2, rng, 20)
    else:
        labels = rng.permutation([0] * n + [1] * n)
        its = [iter(tc1), iter(tc2)]
        events = [next(its[label]) for label in labels]
    matcher = PairMatcher(slop_ns=0, queue_size=n)
    pairs = feed(matcher, events)
    assert pairs == [(int(s), float(k), float(1000 + k)) for k, s in enumerate(stamps)]
    assert matcher.counters.as_dict() == {
        "received_tc1": n,
        "received_tc2": n,
        "matched": n,
        "unmatched_tc1": 0,
        "unmatched_tc2": 0,
        "out_of_order": 0,
        "duplicates": 0,
        "invalid_tc1": 0,
        "invalid_tc2": 0,
        "malformed_tc1": 0,
        "malformed_tc2": 0,
        "discontinuities": 0,
    }
    assert matcher.pending() == (0, 0)


def test_zero_slop_does_not_pair_stamps_one_ns_apart():
    matcher = PairMatcher(slop_ns=0)
    assert feed(matcher, [(0, T0, 1.0), (1, T0 + 1, 2.0)]) == []
    assert matcher.pending() == (1, 1)
    assert matcher.add(1, T0, 3.0) == [(T0, 1.0, 3.0)]
    # the tc2 sample at T0 + 1 is newer than the pair: still queued, not evicted
    assert matcher.pending() == (0, 1)
    assert matcher.counters.total_unmatched == 0


# -- approximate matching -----------------------------------------------------------------------
def test_slop_pairs_each_tc2_with_its_nearest_tc1_despite_jitter():
    rng = np.random.default_rng(3)
    n, period = 500, 1 * MS
    tc1_stamps = T0 + np.arange(n) * period
    jitter = rng.integers(-4 * period // 10, 4 * period // 10 + 1, n)
    tc2_stamps = tc1_stamps + jitter
    tc1, tc2 = stream(0, tc1_stamps), stream(1, tc2_stamps)
    labels = rng.permutation([0] * n + [1] * n)  # random interleaving, each input in order
    its = [iter(tc1), iter(tc2)]
    events = [next(its[label]) for label in labels]
    matcher = PairMatcher(slop_ns=45 * period // 100, queue_size=n)
    pairs = feed(matcher, events)
    assert pairs == [(int(tc1_stamps[k]), float(k), float(1000 + k)) for k in range(n)]
    assert matcher.counters.total_unmatched == 0
    assert matcher.pending() == (0, 0)


def test_closest_candidate_wins_and_ties_go_to_the_older_stamp():
    matcher = PairMatcher(slop_ns=100)
    feed(matcher, [(0, 1000, 1.0), (0, 1100, 2.0), (0, 1200, 3.0)])
    assert matcher.add(1, 1140, 9.0) == [(1100, 2.0, 9.0)]  # 1100 is 40 away, 1200 is 60
    assert matcher.counters.total_unmatched == 1  # 1000 is older than the pair: evicted
    assert matcher.pending() == (1, 0)

    tie = PairMatcher(slop_ns=100)
    feed(tie, [(0, 1100, 1.0), (0, 1200, 2.0)])
    assert tie.add(1, 1150, 9.0) == [(1100, 1.0, 9.0)]
    assert tie.pending() == (1, 0)  # 1200 is newer: kept

    tie_tc1 = PairMatcher(slop_ns=100)  # the same tie with the new sample on tc1
    feed(tie_tc1, [(1, 1100, 1.0), (1, 1200, 2.0)])
    assert tie_tc1.add(0, 1150, 9.0) == [(1150, 9.0, 1.0)]


def test_outside_slop_is_not_matched_and_slop_bound_is_inclusive():
    matcher = PairMatcher(slop_ns=100)
    assert feed(matcher, [(0, 1000, 1.0), (1, 1101, 2.0)]) == []
    assert matcher.add(1, 900, 3.0) == [(1000, 1.0, 3.0)]  # exactly 100 away


def test_5khz_against_1khz_pairs_only_the_1khz_samples():
    rng = np.random.default_rng(5)
    period1 = 200_000  # 5 kHz, ns
    tc1_stamps = T0 + np.arange(5000) * period1
    tc2_nominal = T0 + np.arange(1000) * 5 * period1
    tc2_stamps = tc2_nominal + rng.integers(-40_000, 40_001, 1000)  # jitter within the slop
    tc1, tc2 = stream(0, tc1_stamps), stream(1, tc2_stamps)
    # arrival in stamp order, ties broken at random
    keys = [(s, rng.random()) for _, s, _ in tc1] + [(s, rng.random()) for _, s, _ in tc2]
    events = [e for _, e in sorted(zip(keys, tc1 + tc2, strict=True), key=lambda x: x[0])]
    matcher = PairMatcher(slop_ns=period1 // 2, queue_size=1000)
    pairs = feed(matcher, events)
    assert pairs == [(int(tc2_nominal[k]), float(5 * k), float(1000 + k)) for k in range(1000)]
    c = matcher.counters
    assert c.matched == 1000
    assert matcher.pending() == (4, 0)  # the four tc1 samples after the last pair
    assert c.total_unmatched == 5000 - 1000 - 4
    assert c.out_of_order == c.duplicates == 0
    check_identity(matcher)


# -- ordering ------------------------------------------------------------------------------------
@pytest.mark.parametrize("shuffled", [0, 1])
def test_out_of_order_within_the_queue_is_matched_in_increasing_order(shuffled):
    rng = np.random.default_rng(7)
    n, block = 240, 12
    stamps = T0 + np.arange(n) * MS + rng.integers(0, 1000, n)  # increasing, irregular
    streams = [stream(0, stamps), stream(1, stamps)]
    events = []
    for start in range(0, n, block):
        chunk = streams[shuffled][start : start + block]
        events += [chunk[k] for k in rng.permutation(len(chunk))]  # whole block, shuffled
        events += streams[1 - shuffled][start : start + block]  # partner, in order
    matcher = PairMatcher(slop_ns=0, queue_size=block)
    pairs = feed(matcher, events)
    assert pairs == [(int(s), float(k), float(1000 + k)) for k, s in enumerate(stamps)]
    assert matcher.counters.total_unmatched == matcher.counters.out_of_order == 0


def test_late_samples_are_counted_and_dropped():
    matcher = PairMatcher(slop_ns=0)
    feed(matcher, [(0, 10, 1.0), (0, 20, 2.0), (0, 30, 3.0)])
    assert matcher.add(1, 20, 9.0) == [(20, 2.0, 9.0)]
    assert matcher.counters.total_unmatched == 1  # tc1 at 10 can no longer pair in order
    assert matcher.add(1, 10, 8.0) == []  # older than tc2's last pair
    assert matcher.add(1, 20, 8.0) == []  # equal to it
    assert matcher.add(0, 20, 8.0) == []  # tc1 equal to its last pair
    assert matcher.add(0, 15, 8.0) == []
    c = matcher.counters
    assert c.out_of_order == 4
    assert matcher.pending() == (1, 0)
    assert matcher.add(1, 30, 7.0) == [(30, 3.0, 7.0)]  # later samples still pair
    check_identity(matcher)


def test_approximate_pairs_keep_both_stamps_increasing():
    # tc2 at 1050 pairs with tc1 1000; tc1 1080 would be within slop of tc2 1050 but is newer
    # than the pair on tc1 only; tc2 1040 arriving afterwards is late on tc2
    matcher = PairMatcher(slop_ns=100)
    assert feed(matcher, [(0, 1000, 1.0), (1, 1050, 2.0)]) == [(1000, 1.0, 2.0)]
    assert matcher.add(1, 1040, 3.0) == []
    assert matcher.counters.out_of_order == 1
    assert matcher.add(0, 1080, 4.0) == []  # its only tc2 candidate was used: queued
    assert matcher.pending() == (1, 0)


def test_duplicates_are_counted_and_the_first_value_kept():
    matcher = PairMatcher(slop_ns=0)
    feed(matcher, [(0, 50, 1.0), (0, 70, 2.0)])
    assert matcher.add(0, 70, 5.0) == []  # duplicate of the newest (append path)
    assert matcher.add(0, 50, 6.0) == []  # duplicate of an older one (bisect path)
    assert matcher.counters.duplicates == 2
    assert matcher.pending() == (2, 0)
    assert feed(matcher, [(1, 50, 3.0), (1, 70, 4.0)]) == [(50, 1.0, 3.0), (70, 2.0, 4.0)]
    assert matcher.add(1, 90, 0.0) == []
    assert matcher.add(1, 90, 0.0) == []
    assert matcher.counters.duplicates == 3
    check_identity(matcher)


# -- accounting ----------------------------------------------------------------------------------
def test_missing_stamps_accounting_adds_up():
    rng = np.random.default_rng(13)
    n = 5000
    stamps = T0 + np.arange(n) * 200_000
    keep = [rng.random(n) >= 0.05, rng.random(n) >= 0.05]
    tc1 = stream(0, stamps[keep[0]])
    tc2 = stream(1, stamps[keep[1]])
    events = merge_bursts(tc1, tc2, rng, 5)
    matcher = PairMatcher(slop_ns=0, queue_size=100)
    pairs = feed(matcher, events)
    both = stamps[keep[0] & keep[1]]
    assert [p[0] for p in pairs] == both.tolist()
    c = matcher.counters
    assert c.received == [len(tc1), len(tc2)]
    assert c.matched == len(both)
    pending = matcher.pending()
    assert 2 * c.matched + sum(c.unmatched) == (
        sum(c.received) - sum(pending) - c.out_of_order - c.duplicates
    )
    # every sample without a partner before the last pair was evicted exactly once
    last = both[-1]
    lonely = (stamps <= last) & (keep[0] ^ keep[1])
    assert c.total_unmatched == int(lonely.sum())
    assert c.out_of_order == c.duplicates == 0


def test_queue_overflow_when_one_input_is_silent():
    matcher = PairMatcher(slop_ns=0, queue_size=10)
    pairs = matcher.add_many(0, [T0 + k for k in range(25)], [float(k) for k in range(25)])
    assert pairs == []
    assert matcher.pending() == (10, 0)
    assert matcher.counters.total_unmatched == 15
    check_identity(matcher)
    # the newest ten were kept
    pairs = matcher.add_many(1, [T0 + k for k in range(15, 25)], [-1.0] * 10)
    assert pairs == [(T0 + k, float(k), -1.0) for k in range(15, 25)]
    assert matcher.pending() == (0, 0)


def test_silent_input_that_comes_back_resumes_matching():
    matcher = PairMatcher(slop_ns=0, queue_size=16)
    stamps = [T0 + k * MS for k in range(100)]
    events = []
    for k, s in enumerate(stamps):
        events.append((0, s, float(k)))
        if not 30 <= k < 70:  # tc2 silent for 40 samples, longer than the queue
            events.append((1, s, float(-k)))
    pairs = feed(matcher, events)
    expected = [k for k in range(100) if not 30 <= k < 70]
    assert pairs == [(stamps[k], float(k), float(-k)) for k in expected]
    assert matcher.counters.total_unmatched == 40  # by overflow, then by the pair at 70
    assert matcher.pending() == (0, 0)
    check_identity(matcher)


def test_add_many_equals_add_one_by_one_and_accepts_numpy():
    rng = np.random.default_rng(17)
    stamps = np.sort(rng.choice(10_000, 300, replace=False)).astype(np.int64)
    values = rng.normal(size=300)
    a, b = PairMatcher(slop_ns=20), PairMatcher(slop_ns=20)
    out_a = a.add_many(0, stamps, values) + a.add_many(1, stamps[::2] + 3, values[::2])
    out_b = feed(b, [(0, int(s), float(v)) for s, v in zip(stamps, values, strict=True)])
    out_b += feed(
        b, [(1, int(s) + 3, float(v)) for s, v in zip(stamps[::2], values[::2], strict=True)]
    )
    assert out_a == out_b
    assert all(type(p[0]) is int and type(p[1]) is float for p in out_a)
    assert a.counters == b.counters


def test_counters_as_dict_pending_and_reset():
    matcher = PairMatcher(slop_ns=0, queue_size=5)
    feed(matcher, [(0, 1, 1.0), (0, 2, 2.0), (1, 2, 3.0), (1, 1, 4.0), (0, 3, 5.0), (0, 3, 5.0)])
    assert matcher.counters.as_dict() == {
        "received_tc1": 4,
        "received_tc2": 2,
        "matched": 1,
        "unmatched_tc1": 1,
        "unmatched_tc2": 0,
        "out_of_order": 1,
        "duplicates": 1,
        "invalid_tc1": 0,
        "invalid_tc2": 0,
        "malformed_tc1": 0,
        "malformed_tc2": 0,
        "discontinuities": 0,
    }
    assert matcher.pending() == (1, 0)
    counters = matcher.counters
    matcher.reset()
    assert matcher.pending() == (0, 0)
    assert counters is matcher.counters  # zeroed in place
    assert matcher.counters == PairCounters()
    assert matcher.add(1, 1, 7.0) == []  # no longer late after a reset
    assert matcher.add(0, 1, 8.0) == [(1, 8.0, 7.0)]


# -- validation ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("slop_ns", -1),
        ("queue_size", 0),
        ("queue_size", -3),
        ("slop_ns", 0.5),
        ("queue_size", 2.0),
    ],
)
def test_invalid_configuration_is_refused(name, value):
    with pytest.raises(ValueError, match=rf"{name}.*{re.escape(str(value))}"):
        PairMatcher(**{name: value})


def test_invalid_calls_are_refused():
    matcher = PairMatcher()
    with pytest.raises(ValueError, match="got 2"):
        matcher.add(2, 0, 0.0)
    with pytest.raises(ValueError, match="3 stamps but 2 values"):
        matcher.add_many(0, [1, 2, 3], [1.0, 2.0])
    with pytest.raises(ValueError, match="float64"):
        matcher.add_many(0, np.array([1.0, 2.0]), [1.0, 2.0])
    assert matcher.counters == PairCounters()


# -- property-style ------------------------------------------------------------------------------
def random_scenario(rng):
    """Two irregular, gappy, jittered streams with duplicates and local reordering."""
    n = int(rng.integers(1, 400))
    period = int(rng.integers(50, 500))
    base = np.cumsum(rng.integers(period // 2, 2 * period, n))
    streams = []
    for index in (0, 1):
        stamps = base + rng.integers(-period, period + 1, n) * (rng.random() < 0.7)
        stamps = stamps[rng.random(n) >= rng.uniform(0, 0.3)]  # gaps
        if len(stamps) and rng.random() < 0.5:  # duplicates
            stamps = np.concatenate([stamps, rng.choice(stamps, len(stamps) // 10 + 1)])
        order = np.argsort(
            stamps + rng.integers(0, 1 + int(rng.integers(0, 4 * period)), len(stamps))
        )
        streams.append([(index, int(s)) for s in stamps[order]])  # locally shuffled arrival
    tc1, tc2 = streams
    events = merge_bursts(tc1, tc2, rng, int(rng.integers(1, 30)))
    slop = int(rng.choice([0, int(rng.integers(0, 2 * period))]))
    queue_size = int(rng.integers(1, 60))
    return events, slop, queue_size


@pytest.mark.parametrize("seed", range(300))
def test_random_scenarios_keep_the_invariants(seed):
    rng = np.random.default_rng(seed)
    events, slop, queue_size = random_scenario(rng)
    matcher = PairMatcher(slop_ns=slop, queue_size=queue_size)
    reference = ReferenceMatcher(slop, queue_size)
    identity = {}  # value -> (index, stamp): each message gets a unique value
    pairs = []
    for k, (index, stamp) in enumerate(events):
        value = float(k)
        identity[value] = (index, stamp)
        out = matcher.add(index, stamp, value)
        assert out == reference.add(index, stamp, value)
        assert len(out) <= 1
        pairs += out
        assert sum(matcher.pending()) <= 2 * queue_size
        check_identity(matcher)
    used = set()
    previous = (None, None)
    for stamp1, value1, value2 in pairs:
        assert identity[value1] == (0, stamp1)
        index2, stamp2 = identity[value2]
        assert index2 == 1
        assert abs(stamp1 - stamp2) <= slop
        assert value1 not in used and value2 not in used
        used |= {value1, value2}
        if previous[0] is not None:
            assert stamp1 > previous[0] and stamp2 > previous[1]
        previous = (stamp1, stamp2)
    assert matcher.counters.as_dict() == reference.counters()
    assert matcher.pending() == (len(reference.queues[0]), len(reference.queues[1]))


# -- the batch path ------------------------------------------------------------------------------
def bursts(events):
    """Runs of consecutive events of one input: (index, stamps, values)."""
    out = []
    for index, stamp, value in events:
        if out and out[-1][0] == index:
            out[-1][1].append(stamp)
            out[-1][2].append(value)
        else:
            out.append((index, [stamp], [value]))
    return out


def exact_in_order_scenario(rng):
    """Exact stamps on a common grid, each input missing some, now and then a NaN or a late one."""
    n = int(rng.integers(1, 3000))
    grid = T0 + np.cumsum(rng.integers(1, 4, n)) * MS
    streams = []
    for index in (0, 1):
        stamps = grid[rng.random(n) >= rng.uniform(0, 0.2)]
        values = rng.normal(size=stamps.size) + 1000 * index
        values[rng.random(stamps.size) < rng.uniform(0, 0.01)] = np.nan
        events = [(index, int(s), float(v)) for s, v in zip(stamps, values, strict=True)]
        if events and rng.random() < 0.3:  # a late repeat of an old stamp
            k = int(rng.integers(0, len(events)))
            events.append((index, events[k][1], 5.0))
        streams.append(events)
    return merge_bursts(*streams, rng, int(rng.integers(1, 400)))


def check_batch_equals_one_by_one(events, slop, queue_size):
    one = PairMatcher(slop_ns=slop, queue_size=queue_size)
    batched = PairMatcher(slop_ns=slop, queue_size=queue_size)
    expected = feed(one, events)
    parts = [
        batched.add_batch(index, np.array(stamps, np.int64), np.array(values))
        for index, stamps, values in bursts(events)
    ]
    got = Pairs.concatenate(parts)
    assert (
        list(zip(got.stamps_ns.tolist(), got.tc1.tolist(), got.tc2.tolist(), strict=True))
        == expected
    )
    assert batched.counters == one.counters  # every counter, and the first dropped of each
    assert batched.pending() == one.pending()
    batched._unpark()  # a parked queue holds the same samples as arrays
    assert batched._stamps == one._stamps and batched._last == one._last
    assert batched._values == one._values


@pytest.mark.parametrize("seed", range(150))
def test_batches_of_exact_stamps_in_order_equal_one_by_one(seed):
    rng = np.random.default_rng(1000 + seed)
    queue_size = int(rng.choice([5, 50, 2000]))
    check_batch_equals_one_by_one(exact_in_order_scenario(rng), 0, queue_size)


@pytest.mark.parametrize("seed", range(150))
def test_batches_of_any_scenario_equal_one_by_one(seed):
    rng = np.random.default_rng(seed)
    events, slop, queue_size = random_scenario(rng)
    values = rng.normal(size=len(events))
    values[rng.random(len(events)) < 0.02] = np.inf
    events = [(i, s, float(v)) for (i, s), v in zip(events, values, strict=True)]
    check_batch_equals_one_by_one(events, slop, queue_size)


def test_in_order_exact_batches_take_the_vectorised_path(monkeypatch):
    matcher = PairMatcher(slop_ns=0, queue_size=5000)

    def refuse(*_):
        raise AssertionError("sample-by-sample path taken")

    monkeypatch.setattr(matcher, "_offer", refuse)
    stamps = T0 + np.arange(4000, dtype=np.int64) * MS
    values = np.arange(4000.0)
    keep = np.ones(4000, bool)
    keep[[10, 11, 3000]] = False  # tc2 misses three samples
    assert len(matcher.add_batch(0, stamps[:2000], values[:2000])) == 0
    first = matcher.add_batch(1, stamps[keep][:1998], values[keep][:1998] + 0.5)
    second = matcher.add_batch(0, stamps[2000:], values[2000:])
    third = matcher.add_batch(1, stamps[keep][1998:], values[keep][1998:] + 0.5)
    pairs = Pairs.concatenate([first, second, third])
    assert np.array_equal(pairs.stamps_ns, stamps[keep])
    assert np.array_equal(pairs.tc2, pairs.tc1 + 0.5)
    c = matcher.counters
    assert (c.matched, c.unmatched, c.first_dropped) == (
        3997,
        [3, 0],
        {"unmatched_tc1": T0 + 10 * MS},
    )


def test_invalid_values_are_counted_per_input_and_never_paired():
    matcher = PairMatcher()
    assert matcher.add(0, 10, math.nan) == []
    assert len(matcher.add_batch(0, np.array([20, 30]), np.array([1.0, -math.inf]))) == 0
    assert len(matcher.add_batch(1, np.array([10, 20, 30]), np.array([1.0, 2.0, 3.0]))) == 1
    c = matcher.counters
    assert (c.invalid, c.last_invalid_ns, c.matched) == ([2, 0], [30, 0], 1)
    assert c.first_dropped["invalid_tc1"] == 10
    matcher.discard_pending()  # tc2 at 30 stays without a partner at the end
    assert matcher.pending() == (0, 0) and c.unmatched == [0, 2]
