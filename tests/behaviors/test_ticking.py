"""behaviors.ticking changes a tree's state exactly as py_trees does: random trees of
Sequences and Selectors (with and without memory), Retry and Inverter decorators and scripted
leaves are built twice, once from py_trees' classes and once from behaviors.ticking's, ticked
side by side, and compared node by node after every tick (status, current child, and the
order of every initialise/update/terminate call)."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from behaviors import ticking

_STATUSES = (Status.SUCCESS, Status.FAILURE, Status.RUNNING)


def _leaf_class(base):
    class Scripted(base):
        """Returns the next status of its script on each update; records its calls."""

        def __init__(self, name, script, calls):
            super().__init__(name)
            self.script, self.calls, self.step = script, calls, 0

        def initialise(self):
            self.calls.append((self.name, "initialise"))

        def update(self):
            status = self.script[self.step % len(self.script)]
            self.step += 1
            self.calls.append((self.name, "update", status))
            return status

        def terminate(self, new_status):
            self.calls.append((self.name, "terminate", new_status))

    return Scripted


def _kit(quiet: bool):
    if quiet:
        return (ticking.Sequence, ticking.Selector, ticking.Retry, ticking.Inverter,
                _leaf_class(ticking.QuietBehaviour))
    return (py_trees.composites.Sequence, py_trees.composites.Selector,
            py_trees.decorators.Retry, py_trees.decorators.Inverter,
            _leaf_class(py_trees.behaviour.Behaviour))


def _plan(rng, depth=0):
    """A random tree shape, built the same way by either kit."""
    roll = rng.random()
    if depth >= 4 or roll < 0.3:
        return ("leaf", [_STATUSES[i] for i in rng.integers(0, 3, int(rng.integers(1, 6)))])
    if roll < 0.4:
        return ("retry", int(rng.integers(1, 4)), _plan(rng, depth + 1))
    if roll < 0.5:
        return ("invert", _plan(rng, depth + 1))
    kind = "sequence" if rng.random() < 0.5 else "selector"
    return (kind, bool(rng.random() < 0.5),
            [_plan(rng, depth + 1) for _ in range(int(rng.integers(0, 5)))])


def _build(plan, kit, calls, names):
    sequence, selector, retry, inverter, leaf = kit
    name = f"n{next(names)}"
    if plan[0] == "leaf":
        return leaf(name, plan[1], calls)
    if plan[0] == "retry":
        return retry(name, _build(plan[2], kit, calls, names), plan[1])
    if plan[0] == "invert":
        return inverter(name, _build(plan[1], kit, calls, names))
    cls = sequence if plan[0] == "sequence" else selector
    return cls(name, memory=plan[1], children=[_build(p, kit, calls, names) for p in plan[2]])


def _state(root):
    return [(node.name, node.status,
             getattr(getattr(node, "current_child", None), "name", None))
            for node in root.iterate()]


@pytest.mark.parametrize("seed", range(40))
def test_random_trees_tick_as_with_py_trees(seed):
    rng = np.random.default_rng(seed)
    guard = ("leaf", [Status.FAILURE, Status.FAILURE, Status.RUNNING, Status.SUCCESS])
    plan = ("selector", False, [guard, _plan(rng), ("sequence", True, [_plan(rng), _plan(rng)])])
    trees, calls = [], []
    # py_trees, ours ticked, ours run (no generators) with an observer
    for quiet in (False, True, True):
        log: list = []
        root = _build(plan, _kit(quiet), log, iter(range(10_000)))
        trees.append(root)
        calls.append(log)
    plain, quiet, direct = trees
    for tick in range(30):
        if tick == 17:  # an interruption from above, as a higher-priority branch does
            for root in trees:
                root.stop(Status.INVALID)
        visited = [[(n.name, n.status) for n in root.tick()] for root in (plain, quiet)]
        observed: list = []  # what a visitor sees of the plain call, in order
        ticking.run_observed(direct, lambda n, seen=observed: seen.append((n.name, n.status)))
        assert visited[0] == visited[1] == observed, f"tick {tick}"
        assert _state(plain) == _state(quiet) == _state(direct), f"tick {tick}"
        assert calls[0] == calls[1] == calls[2], f"tick {tick}"
    assert any(call[1] == "terminate" for call in calls[1])


def test_run_ticks_a_node_from_elsewhere_and_an_own_tick_through_its_generator():
    """A py_trees Parallel among our nodes, and a subclass of ours with a tick of its own,
    are run through their ``tick``."""
    calls: list = []
    leaf = _leaf_class(ticking.QuietBehaviour)

    class Counted(leaf):
        def tick(self):
            calls.append((self.name, "own tick"))
            yield from super().tick()

    def tree():
        parallel = py_trees.composites.Parallel(
            "p", policy=py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=False),
            children=[leaf("a", [Status.SUCCESS], calls), Counted("b", [Status.RUNNING], calls)])
        return ticking.Sequence("root", memory=False, children=[parallel]), parallel

    root, parallel = tree()
    ticking.run(root)
    assert ("b", "own tick") in calls and ("a", "update", Status.SUCCESS) in calls
    assert (root.status, parallel.status) == (Status.RUNNING, Status.RUNNING)
    # A visitor sees the generator's nodes too, as py_trees' own tick yields them.
    (observed_root, _), (ticked_root, _) = tree(), tree()
    observed: list = []
    ticking.run_observed(observed_root, lambda n: observed.append((n.name, n.status)))
    assert observed == [(n.name, n.status) for n in ticked_root.tick()]
    assert [n for n, _ in observed] == ["a", "b", "p", "root"]


def test_an_invalid_status_is_logged_and_made_invalid(caplog):
    class Broken(ticking.QuietBehaviour):
        def update(self):
            return "done"

    node = Broken("broken")
    for _ in node.tick():
        pass
    assert node.status == Status.INVALID


def test_peek_reads_what_the_blackboard_client_reads():
    from behaviors import blackboard as keys
    from behaviors.base import MissionBehaviour

    class Peeker(MissionBehaviour):
        def update(self):
            return Status.SUCCESS

    keys.reset()
    node = Peeker("peeker")
    node.blackboard.register_key(key=keys.FAILSAFE, access=py_trees.common.Access.WRITE)
    for value in (None, "battery_critical"):
        node.blackboard.set(keys.FAILSAFE, value)
        assert node.peek(keys.FAILSAFE) == node.blackboard.get(keys.FAILSAFE) == value
    py_trees.blackboard.Blackboard.enable_activity_stream()
    try:
        assert node.peek(keys.FAILSAFE) == "battery_critical"
        stream = py_trees.blackboard.Blackboard.activity_stream
        assert any(item.key == keys.FAILSAFE for item in stream.data)  # the read is recorded
    finally:
        py_trees.blackboard.Blackboard.disable_activity_stream()
    py_trees.blackboard.Blackboard.unset(keys.FAILSAFE)
    with pytest.raises(KeyError):
        node.peek(keys.FAILSAFE)
    keys.reset()


def test_a_feedback_message_set_for_later_reads_as_formatted():
    """feedback_later keeps the values and formats them when the message is read, as the
    f-string it replaces would have; a plain assignment still replaces it."""
    from behaviors.ticking import QuietBehaviour

    class Leaf(QuietBehaviour):
        def update(self) -> Status:
            return Status.RUNNING

    node = Leaf(name="node")
    assert node.feedback_message == ""
    values = (3, 7, 12.345, -0.05, 1e-7, 2.5)
    node.feedback_later("leg {}/{} at {:.1f}, {:.1f} ({:g}), {} m", *values)
    a, b, c, d, e, f = values
    assert node.feedback_message == f"leg {a}/{b} at {c:.1f}, {d:.1f} ({e:g}), {f} m"
    assert node.feedback_message == "leg 3/7 at 12.3, -0.1 (1e-07), 2.5 m"
    node.feedback_message = "plain"
    assert node.feedback_message == "plain"
