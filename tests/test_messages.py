"""The sandbox's messages are declared once (ata.runtime.messages) and both sides use them:
every decision slot of the kernel has its operation, its proxy on the host, and its handler in
the decision process."""

from pathlib import Path

import ata
from ata.core.kernel import DECISION_SLOTS
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
