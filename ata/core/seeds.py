"""Secret root seeds: ``env:NAME`` in a mission's or suite's seed reads the seed from the
environment, and results show ``secret:`` and the start of its SHA-256, never the seed."""

from __future__ import annotations

import hashlib
import os
from typing import Any

from ata.core.errors import MissionError


SECRET_SEED_MIN = 2**32
"""A secret seed below it could be found from its hash by trying them all."""


def seed_hash(seed: int) -> str:
    """``secret:`` and the first 16 hex digits of the SHA-256 of the seed's decimal digits."""
    return "secret:" + hashlib.sha256(str(int(seed)).encode()).hexdigest()[:16]


def secret_seed(value: Any) -> int | None:
    """The seed an ``env:NAME`` value names (read from the environment), None for any other
    value; a MissionError naming the fix for a missing, malformed or guessable one, and for
    the ``secret:`` label of a resolved file."""
    if not isinstance(value, str):
        return None
    if value.startswith("secret:"):
        raise MissionError("[mission]", "seed", f"{value!r} is the hash of a secret seed, not "
                           "a seed: give the seed again as 'env:NAME', NAME an environment "
                           "variable that holds it")
    if not value.startswith("env:"):
        return None
    name = value[4:]
    text = os.environ.get(name)
    if not name or text is None:
        raise MissionError("[mission]", "seed", f"{value!r} reads the environment variable "
                           f"{name!r}, which is not set: export {name or 'NAME'}=N, N a secret "
                           "integer (python -c 'import secrets; print(secrets.randbits(63))')")
    try:
        seed = int(text.strip())
    except ValueError:
        raise MissionError("[mission]", "seed", f"the environment variable {name!r} holds "
                           "no integer") from None
    if not SECRET_SEED_MIN <= seed < 2**63:
        raise MissionError("[mission]", "seed", f"the secret seed in {name!r} must lie in "
                           f"[2**32, 2**63): a smaller one is found from its hash by trying "
                           "them all (python -c 'import secrets; print(secrets.randbits(63))')")
    return seed
