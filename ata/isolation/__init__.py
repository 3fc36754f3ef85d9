"""The sandbox's host side (``--isolate``): the decision process and its pool (`process`), the
proxies that fill the decision slots (`proxies`), the registry of methods the host never
imports (`remote`), and the backend that puts them on the run path (`backend`). The sandbox's
own side is ``ata.runtime`` (`decider`, `sandbox`, `frames`)."""

from ata.isolation.backend import Isolated, require_sandbox

__all__ = ["Isolated", "require_sandbox"]
