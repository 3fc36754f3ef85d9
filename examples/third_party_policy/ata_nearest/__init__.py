"""ata-nearest: an example third-party policy package (the file
examples/policies/nearest_capable.py, made installable)."""

from ata import hookimpl

from ata_nearest.policy import NearestCapable

__all__ = ["NearestCapable"]


@hookimpl
def ata_register_components(register):
    register("policy", "nearest_capable", NearestCapable)
