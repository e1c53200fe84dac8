"""The semantic sets' manifest (tools/semantic_sets.py, assets/semantics/sets.toml): every set's files match their
recorded count and content hash (the frozen benches' bytes never change), every file under assets/semantics/ belongs
to one set, and the look-ups refuse what the manifest does not name."""

import pytest

from tools import semantic_sets


def test_every_set_matches_its_count_and_hash_and_every_file_belongs_to_a_set():
    assert semantic_sets.check() == []


def test_each_set_lies_in_its_roles_folder_and_says_who_reads_it_or_why_it_stays():
    sets = semantic_sets.load()
    assert {s.role for s in sets.values()} == set(semantic_sets.ROLES)
    for s in sets.values():
        assert s.folder.parent == semantic_sets.FOLDER / s.role, s.name
        assert s.readers or s.why, s.name
        assert len(s.sha256) == 64 and s.about, s.name
    # the frozen benches are read by the bench alone (and the tests)
    for s in semantic_sets.select(role="bench"):
        assert set(s.readers) - {"corpus", "tests"} == {"bench"}, s.name


def test_a_changed_byte_an_unlisted_file_and_a_missing_file_are_reported(tmp_path, monkeypatch):
    folder = tmp_path / "semantics"
    (folder / "bench" / "a").mkdir(parents=True)
    (folder / "bench" / "a" / "bench.jsonl").write_text('{"text": "x"}\n')
    manifest = folder / "sets.toml"
    digest = semantic_sets.digest(folder / "bench" / "a")
    entry = '[sets."bench/a"]\nrole = "bench"\nreaders = ["bench"]\nfiles = ["bench.jsonl"]\nabout = "a"\n'
    manifest.write_text(entry + f'texts = 1\nsha256 = "{digest}"\n')
    monkeypatch.setattr(semantic_sets, "FOLDER", folder)
    monkeypatch.setattr(semantic_sets, "ROOT", tmp_path)
    assert semantic_sets.check(manifest) == []
    (folder / "bench" / "a" / "bench.jsonl").write_text('{"text": "y"}\n')
    assert [p.split(":")[0] for p in semantic_sets.check(manifest)] == ["bench/a"]
    (folder / "bench" / "stray.jsonl").write_text("")
    assert any("in no set" in p for p in semantic_sets.check(manifest))
    (folder / "bench" / "a" / "bench.jsonl").unlink()
    assert any("missing" in p for p in semantic_sets.check(manifest))


def test_look_ups_name_the_valid_choices():
    assert semantic_sets.path("dev/v2").name == "dev.jsonl"
    assert semantic_sets.path("dev/situations_blind", "second_reader.jsonl").is_file()
    with pytest.raises(KeyError, match="valid"):
        semantic_sets.get("dev/nope")
    with pytest.raises(ValueError, match="valid"):
        semantic_sets.select(reader="nobody")
    with pytest.raises(ValueError, match="data files"):
        semantic_sets.path("train/corpora")  # four files: name one
    with pytest.raises(FileNotFoundError, match="holds"):
        semantic_sets.path("dev/v2", "test.jsonl")
    names = [s.name for s in semantic_sets.select(reader="training")]
    assert names[0] == "train/corpora" and all(n.startswith("train/") for n in names)
