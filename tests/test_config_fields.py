"""Old episode.json files stay readable only if every change to RunConfig's fields is described: a removed
field in `config.REMOVED` (with the value that behaves as today's code), an added one whose default changes
what runs did in `config.ADDED` (with the value the old code behaved as). This test compares the fields
with the list in tests/config_fields.txt, so neither kind of change goes in unnoticed.

After describing the change (or deciding that an added field's default keeps the old behaviour), write the
list again: ``python tests/test_config_fields.py --write``."""

import sys
from pathlib import Path

from activesplat.config import ADDED, REMOVED, option_paths

LIST = Path(__file__).with_name("config_fields.txt")


def current_fields() -> list[str]:
    return sorted(option_paths())


def test_every_removed_or_added_field_is_described_for_old_episode_files():
    listed = [line for line in LIST.read_text().splitlines() if line and not line.startswith("#")]
    now = current_fields()
    gone = sorted(set(listed) - set(now) - set(REMOVED))
    new = sorted(set(now) - set(listed))
    assert not gone, (f"fields removed from RunConfig: {gone}. Add each to config.REMOVED with the value "
                      f"that behaves as today's code, then run `python tests/{Path(__file__).name} --write`")
    assert not new, (f"fields added to RunConfig: {new}. If a default changes what runs did before, add the "
                     f"field to config.ADDED with the old behaviour's value; then run "
                     f"`python tests/{Path(__file__).name} --write`")
    assert not set(REMOVED) & set(now), "a field in config.REMOVED is a field again"
    unknown = set(ADDED) - set(now)
    assert not unknown, f"config.ADDED names fields RunConfig does not have: {unknown}"


def test_the_mapper_drops_the_same_removed_fields_from_an_old_mapper_json():
    from activesplat.splat.config import REMOVED_FIELDS

    assert {"mapper." + name for name in REMOVED_FIELDS} == {p for p in REMOVED if p.startswith("mapper.")}


def test_the_mapper_reads_the_same_added_fields_of_an_old_mapper_json():
    from activesplat.splat.config import ADDED_FIELDS

    assert {"mapper." + name: old for name, old in ADDED_FIELDS.items()} == {
        p: old for p, old in ADDED.items() if p.startswith("mapper.")}


if __name__ == "__main__" and sys.argv[1:] == ["--write"]:
    header = "# RunConfig's settable fields (tests/test_config_fields.py)\n"
    LIST.write_text(header + "\n".join(current_fields()) + "\n")
    print(f"wrote {LIST}")
