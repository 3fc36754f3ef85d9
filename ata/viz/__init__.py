"""Pictures of one episode: replay a scenario with a recorder attached (`record.py`), draw its
map, timeline and human states (`draw.py`); `ata show` (`show.py`) ties them to a run folder or
a mission file. Recording is opt-in: nothing here runs unless a scenario is replayed."""
