"""A suite method of several training seeds (`seeds = [...]`, docs/evaluation.md "Suites"):
one method a seed, each reading its own weights."""

import pytest

from ata.core.errors import MissionError


def test_a_method_of_several_seeds_is_one_method_a_seed_with_its_weights(tmp_path):
    from ata.experiment.suites import load_suite
    path = tmp_path / "s.toml"
    head = '[suite]\nsettings = ["a", "b"]\n[[method]]\nname = "mine"\nmission = "builtin:greedy"\n'
    path.write_text(head + 'seeds = [3, 0]\nset = ["greedy.weights=\'w{seed}\'"]\n'
                    '[method.setting.b]\nset = ["greedy.other=\'b{seed}\'"]\n')
    got = [(m.name, m.overrides, m.per_setting) for m in load_suite(path).methods]
    assert got == [("mine seed 3", ["greedy.weights='w3'"], {"b": ["greedy.other='b3'"]}),
                   ("mine seed 0", ["greedy.weights='w0'"], {"b": ["greedy.other='b0'"]})]
    for seeds, set_, match in (("[1, 1]", "w{seed}", "distinct integers"),
                               ("[-1]", "w{seed}", "distinct integers"),
                               ("[]", "w{seed}", "distinct integers"),
                               ("[1, 2]", "w", "needs {seed}")):
        path.write_text(head + f'seeds = {seeds}\nset = ["greedy.weights=\'{set_}\'"]\n')
        with pytest.raises(MissionError, match=match):
            load_suite(path)
