"""The sandbox's messages are declared once (ata.runtime.messages) and both sides use them:
every decision slot of the kernel has its operation, its proxy on the host, and its handler in
the decision process."""

from pathlib import Path

import ata
from ata.core.components import DECISION_SLOTS
from ata.isolation.proxies import PROXIES
from ata.runtime.decider import Decider
from ata.runtime.messages import OPERATIONS, SLOT_OPERATIONS, Op


def test_every_decision_slot_has_its_operation_proxy_and_handler():
    assert set(SLOT_OPERATIONS) == set(DECISION_SLOTS)
    assert set(PROXIES) == set(DECISION_SLOTS)
    for slot in DECISION_SLOTS:
        op = SLOT_OPERATIONS[slot]
        assert OPERATIONS[op].slot == slot
        assert callable(getattr(Decider, Decider.HANDLERS[op])), slot


def test_every_operation_is_declared_once_and_answered_by_someone():
    assert set(OPERATIONS) == set(Op)
    host_only = {Op.RESOLVE, Op.PROBE, Op.INIT, Op.CLOSE}     # answered by the serve loop
    assert set(Decider.HANDLERS) == set(Op) - host_only


def test_no_side_writes_an_operation_as_a_bare_string():
    root = Path(ata.__file__).parent
    for path in [*root.joinpath("isolation").glob("*.py"), root / "runtime" / "decider.py"]:
        text = path.read_text(encoding="utf-8")
        for op in Op:
            assert f'"op": "{op.value}"' not in text, (path.name, op)
            assert f'op == "{op.value}"' not in text, (path.name, op)


class _FakeLink:
    """A batch of 2 scenarios whose process answers each call with `answers[op]` (None: the
    call timed out), recording each request."""

    batch = 2

    def __init__(self, answers):
        self.answers, self.sent = answers, []

    def request(self, op, epoch, time, previous, observed, inherent, rng, channel, **extra):
        return {"op": op, **extra}

    def call(self, req, where, fatal):
        self.sent.append((req, fatal))
        return self.answers[req["op"]]

    def allocation(self, arrays, where):
        from ata.core.state import Allocation
        return Allocation(arrays["robot"], arrays["navigator"], arrays["classifier"])


def test_every_single_choice_proxy_forwards_its_operation_with_its_hook_arguments():
    import numpy as np
    from types import SimpleNamespace

    from ata.core.mission import SLOT_HOOKS
    from ata.core.state import Allocation

    alloc = {f: np.zeros((2, 3), dtype=np.int64) for f in ("robot", "navigator", "classifier")}
    answers = {op: ({}, alloc) for op in Op}
    answers[Op.CONDITION] = ({}, {"active": np.array([True, False])})
    previous = Allocation(*(np.ones((2, 3), dtype=np.int64) for _ in range(3)))
    for slot, hook in SLOT_HOOKS.items():
        link = _FakeLink(answers)
        proxy = PROXIES[slot](link, slot, "m")
        op = OPERATIONS[SLOT_OPERATIONS[slot]]
        ctx = SimpleNamespace(epoch=1, time=0.0, previous=previous, observed=None,
                              inherent=None, rng=None, channel=None, reallocatable=[True, True])
        args = [np.array([True, True])] * len(op.hook_args)
        out = getattr(proxy, hook)(ctx, *args)
        (req, fatal), = link.sent
        assert req["op"] == op.op and not fatal
        assert set(op.hook_args) <= set(req), slot
        if slot == "condition":
            assert out.tolist() == [True, False]
        else:
            assert isinstance(out, Allocation) and (out.robot == 0).all()
        # a call that timed out keeps what is in force
        link = _FakeLink({o: None for o in Op})
        out = getattr(PROXIES[slot](link, slot, "m"), hook)(ctx, *args)
        assert (out is previous) if slot != "condition" else not out.any()
