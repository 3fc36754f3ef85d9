"""ATA-HRL (the paper's method) as optional plugins: everything of it lives in this package.

- ``ita`` (ata.plugins.ata_hrl.ita): the attention ITA policy ``attention`` and the trainer
  ``ata_hrl``;
- ``ctr`` (ata.plugins.ata_hrl.ctr): conditional task reallocation ``ctr`` (pi_C and pi_TR);
- ``aux`` (ata.plugins.ata_hrl.aux): the auxiliary state reconstruction ``aux``.

Modules: ``decoder`` (capacity-aware decoding in numpy) and its step ``inputs``, ``network``
(the torch networks), ``decode`` (running the decoder with a network), ``features``,
``components``, ``rewards``, ``checkpoint``, ``trainer`` and its ``phases``. It uses only
ata's public plugin API.
"""
