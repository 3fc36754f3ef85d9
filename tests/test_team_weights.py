"""Teams of other sizes: a mission names a family of shipped weights (the default,
``builtin:ata_hrl``), and validation resolves it to the member that suits the team; the resolved
mission records the member and `ata run`'s summary names it."""

from types import SimpleNamespace

import pytest

from ata.experiment import runner
from ata.session import load_session
from ata.runtime.inputs import family, shipped_setting, team_distance, weights_for

LEARNED = ["components.initial='attention'", "components.condition='ctr'",
           "components.reallocation='ctr'", "components.reconstructors=['aux']"]


def team(setting, humans, robots, tasks):
    return SimpleNamespace(setting=setting, humans=humans, robots=robots, tasks=tasks)


def test_a_family_lists_its_members_by_setting():
    assert family("ata_hrl") == {"a": "ata_hrl_a", "b": "ata_hrl_b_ft"}
    assert family("ata_hrl_wo_aux") == {"a": "ata_hrl_wo_aux_a", "b": "ata_hrl_wo_aux_b_ft"}
    assert family("tr_pomdp") == {"a": "tr_pomdp_a"}
    assert family("no_such_family") == {}


@pytest.mark.parametrize("sizes, member", [
    (team("a", 6, 8, 60), "ata_hrl_a"), (team("b", 12, 16, 130), "ata_hrl_b_ft"),
    (team("custom", 3, 4, 30), "ata_hrl_a"), (team("custom", 7, 9, 70), "ata_hrl_a"),
    (team("custom", 9, 12, 90), "ata_hrl_b_ft"), (team("custom", 20, 28, 250), "ata_hrl_b_ft")])
def test_a_family_resolves_to_the_member_of_the_nearest_setting(sizes, member):
    assert weights_for("builtin:ata_hrl", sizes) == f"builtin:{member}"


def test_a_named_file_or_a_path_is_never_changed():
    big = team("custom", 20, 28, 250)
    assert weights_for("builtin:ata_hrl_a", big) == "builtin:ata_hrl_a"
    assert weights_for("runs/x/best.pt", big) == "runs/x/best.pt"
    assert weights_for("builtin:tr_pomdp", big) == "builtin:tr_pomdp_a"    # one member only
    assert shipped_setting("builtin:ata_hrl_b_ft") == "b"
    assert shipped_setting("runs/x/best.pt") is None


def test_the_distance_is_symmetric_in_log_size():
    assert team_distance(6, 8, 60, "a") == 0.0
    assert team_distance(12, 16, 120, "a") == pytest.approx(team_distance(3, 4, 30, "a"))


def test_a_custom_team_loads_and_names_the_weights_of_its_size():
    session = load_session(None, [*LEARNED, "mission.setting='custom'",
                                         "mission.humans=20", "mission.robots=28",
                                         "mission.tasks=250"])
    resolved = session.mission.to_toml()
    for comp in ("attention", "ctr", "aux"):
        assert session.mission.component_settings[comp].checkpoint == "builtin:ata_hrl_b_ft"
    assert 'checkpoint = "builtin:ata_hrl_b_ft"' in resolved
    assert "builtin:ata_hrl\"" not in resolved
    (line,) = runner.weights_rows(session)
    assert line[0] == "weights" and line[1].startswith("builtin:ata_hrl_b_ft (read by ")
    assert "setting b, the nearest to this team's size" in line[1]


def test_setting_a_keeps_a_weights_and_an_explicit_file_wins():
    session = load_session(None, LEARNED + ["attention.checkpoint='builtin:ata_hrl'",
                                                   "ctr.checkpoint='builtin:ata_hrl'"])
    assert session.mission.component_settings["ctr"].checkpoint == "builtin:ata_hrl_a"
    session = load_session(None, [*LEARNED, "mission.setting='b'",
                                         "ctr.checkpoint='builtin:ata_hrl_a'"])
    s = session.mission.component_settings
    assert (s["ctr"].checkpoint, s["attention"].checkpoint) == ("builtin:ata_hrl_a",
                                                                "builtin:ata_hrl_b_ft")
