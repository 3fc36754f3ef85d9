"""ATA-HRL (the paper's method) as optional plugins: everything of it lives in this package.

- ``ita`` (ata.plugins.ata_hrl.ita): the attention ITA policy ``attention``;
- ``ctr`` (ata.plugins.ata_hrl.ctr): conditional task reallocation ``ctr`` (pi_C and pi_TR);
- ``aux`` (ata.plugins.ata_hrl.aux): the auxiliary state reconstruction ``aux``;
- the trainer ``ata_hrl`` (ata.plugins.ata_hrl.train), loaded when a training mission names it.

Modules: ``decoder`` (capacity-aware decoding in numpy) and its step ``inputs``, ``arch`` (the
networks' sizes), ``network`` (the torch networks, for training), ``infer`` (the same networks'
forward passes in numpy, which every decision uses: a run needs no torch), ``decode`` (running
the decoder with a network), ``logprob`` (a decode's log-probabilities, for an update),
``features``, ``components``, ``rewards``, ``checkpoint``, ``trainer`` and its ``phases``. It
uses only ata's public plugin API.
"""
