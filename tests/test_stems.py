"""Output stems of a batch: unique, stable, the plain name whenever it is unique."""

import pytest

from wheelcal.batch.stems import unique_stems


def _touch(root, *names):
    paths = []
    for name in names:
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"")
        paths.append(p)
    return paths


def test_unique_names_keep_their_stem_and_shared_names_get_the_shortest_folder_suffix(tmp_path):
    paths = _touch(
        tmp_path, "day1/x/s.mcap", "day2/x/s.mcap", "day3/s.mcap", "day1/t.mcap", "u.mcap"
    )
    stems = unique_stems(paths)
    assert [stems[str(p)] for p in paths] == ["day1__x__s", "day2__x__s", "day3__s", "t", "u"]


def test_stems_do_not_depend_on_order_or_spelling(tmp_path, monkeypatch):
    paths = _touch(tmp_path, "a/s.mcap", "b/s.mcap", "c/r.mcap")
    first = unique_stems(paths)
    monkeypatch.chdir(tmp_path / "c")
    relative = ["../a/s.mcap", "../b/./s.mcap", "r.mcap"]
    again = unique_stems(reversed(relative))
    assert [again[p] for p in relative] == [first[str(p)] for p in paths] == ["a__s", "b__s", "r"]


def test_a_derived_stem_never_takes_another_inputs_name(tmp_path):
    # "a/s.mcap" would become "a__s", which a real file already is: lengthen the suffix.
    paths = _touch(tmp_path, "q/a/s.mcap", "r/b/s.mcap", "a__s.mcap")
    stems = unique_stems(paths)
    assert stems[str(paths[2])] == "a__s"
    assert stems[str(paths[0])] == "q__a__s" and stems[str(paths[1])] == "b__s"
    assert len(set(stems.values())) == 3


def test_the_same_file_twice_is_refused_by_name(tmp_path):
    (p,) = _touch(tmp_path, "a/s.mcap")
    with pytest.raises(ValueError, match="same recording"):
        unique_stems([p, tmp_path / "a" / ".." / "a" / "s.mcap"])
