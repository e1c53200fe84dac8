"""The semantic reducer's text sets, as ``assets/semantics/sets.toml`` names them: one loader for every reader.

    python -m tools.semantic_sets            # list the sets and check each against the manifest
    python -m tools.semantic_sets --write    # rewrite the manifest's text counts and content hashes

Each set lives in its own folder, ``assets/semantics/<role>/<set>/``, and is named by that path (``"bench/v3"``):
its role (``train``: read to fit something; ``dev``: read to select, calibrate or judge before shipping; ``bench``:
frozen, read only to report), the tools that read it (:data:`READERS`), its data files in reading order, its text
count and its content hash (:func:`digest`: every file of its folder, the writer's brief and README included). A set
that nothing reads says why it stays. The manifest lists the sets in reading order: a reader that reads several sets
reads them in that order (:func:`select`). ``tests/test_semantic_sets.py`` checks every set's count and hash, and
that every file under ``assets/semantics/`` belongs to one set.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import hashlib
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "assets" / "semantics"
MANIFEST = FOLDER / "sets.toml"
ROLES = ("train", "dev", "bench")
READERS = {
    "training": "tools.train_semantics trains the semantic head on it",
    "calibration": "tools.train_semantics selects the head and fits its temperature, cut points and threshold on it",
    "distillation": "tools.train_semantics distils the student encoder on its texts (labels unused)",
    "detector": "tools.train_nomotion trains the learned no-motion detector on it",
    "vote": "tools.semantics_knn builds the vote's table from it, or chooses the vote on it",
    "system dev": "tools.semantics_system_dev and tools.nomotion_frontier judge the whole system on it",
    "corpus": "tools.semantics_corpus keeps the generated corpus's lines out of it",
    "label agreement": "tools.label_agreement compares its writer's labels with a second reader's",
    "bench": "experiments.bench_semantics reports on it (frozen: nothing is tuned on it)",
    "tests": "only the tests read it (what they check is in its why)",
}


@dataclasses.dataclass(frozen=True)
class SemanticSet:
    """One set of the manifest: ``files`` are the data files its readers read, in reading order."""

    name: str
    role: str
    readers: tuple[str, ...]
    files: tuple[Path, ...]
    texts: int | None
    sha256: str
    about: str
    why: str = ""

    @property
    def folder(self) -> Path:
        return FOLDER / self.name

    def file(self, name: str | None = None) -> Path:
        """Its one data file, or the file ``name`` of its folder (a second reader's labels, a raw file)."""
        if name is None:
            if len(self.files) != 1:
                raise ValueError(f"set {self.name!r} has {len(self.files)} data files; name one of {self.file_names}")
            return self.files[0]
        path = self.folder / name
        if not path.is_file():
            present = sorted(p.name for p in self.folder.iterdir())
            raise FileNotFoundError(f"set {self.name!r} has no file {name!r}; its folder holds {present}")
        return path

    @property
    def file_names(self) -> list[str]:
        return [p.relative_to(self.folder).as_posix() for p in self.files]


def _parse(name: str, entry: dict) -> SemanticSet:
    known = {"role", "readers", "files", "texts", "sha256", "about", "why"}
    if unknown := set(entry) - known:
        raise ValueError(f"set {name!r}: unknown keys {sorted(unknown)}; valid: {sorted(known)}")
    role = entry.get("role")
    if role not in ROLES or name.split("/")[0] != role or name.count("/") != 1:
        raise ValueError(f"set {name!r}: its name must be '<role>/<folder>' with role one of {ROLES} (role {role!r})")
    readers = tuple(entry.get("readers", ()))
    if bad := [r for r in readers if r not in READERS]:
        raise ValueError(f"set {name!r}: unknown readers {bad}; valid: {list(READERS)}")
    if not readers and not entry.get("why"):
        raise ValueError(f"set {name!r}: nothing reads it, so the manifest must say why it stays (a 'why' key)")
    if not entry.get("files"):
        raise ValueError(f"set {name!r}: no data files")
    return SemanticSet(
        name=name,
        role=role,
        readers=readers,
        files=tuple(FOLDER / name / f for f in entry["files"]),
        texts=entry.get("texts"),
        sha256=entry.get("sha256", ""),
        about=entry.get("about", ""),
        why=entry.get("why", ""),
    )


@functools.lru_cache(maxsize=4)
def load(path: Path = MANIFEST) -> dict[str, SemanticSet]:
    """Every set of the manifest by name, in the manifest's order."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    return {name: _parse(name, entry) for name, entry in data.get("sets", {}).items()}


def get(name: str) -> SemanticSet:
    sets = load()
    if name not in sets:
        raise KeyError(f"no semantic set {name!r} in {MANIFEST.relative_to(ROOT)}; valid: {list(sets)}")
    return sets[name]


def path(name: str, file: str | None = None) -> Path:
    """The data file of set ``name`` (:meth:`SemanticSet.file`)."""
    return get(name).file(file)


def files(name: str) -> tuple[Path, ...]:
    """The data files of set ``name``, in reading order."""
    return get(name).files


def select(role: str | None = None, reader: str | None = None) -> list[SemanticSet]:
    """The sets of ``role`` read by ``reader`` (either may be None: any), in the manifest's order."""
    if role is not None and role not in ROLES:
        raise ValueError(f"unknown role {role!r}; valid: {ROLES}")
    if reader is not None and reader not in READERS:
        raise ValueError(f"unknown reader {reader!r}; valid: {list(READERS)}")
    return [s for s in load().values() if role in (None, s.role) and reader in (None, *s.readers)]


def _folder_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


def digest(folder: Path) -> str:
    """A folder's content hash: the sha256 of one line ``<relative path>\\t<sha256 of its bytes>`` per file, in path
    order (so a renamed, added or removed file changes it as a changed byte does)."""
    h = hashlib.sha256()
    for p in _folder_files(folder):
        h.update(f"{p.relative_to(folder).as_posix()}\t{hashlib.sha256(p.read_bytes()).hexdigest()}\n".encode())
    return h.hexdigest()


def count(s: SemanticSet) -> int | None:
    """The texts of a set: the lines of its JSON Lines data files (None for a set of no texts: a model)."""
    texts = [p for p in s.files if p.suffix == ".jsonl"]
    if not texts:
        return None
    return sum(1 for p in texts for line in p.read_text().splitlines() if line.strip())


def check(manifest: Path = MANIFEST) -> list[str]:
    """What disagrees with the manifest: a missing data file, a count or a hash that changed, a file under
    ``assets/semantics/`` that no set holds, a set folder inside another."""
    sets = load(manifest)
    problems = []
    folders = {s.folder for s in sets.values()}
    for s in sets.values():
        if any(f in s.folder.parents for f in folders):
            problems.append(f"{s.name}: its folder is inside another set's")
        missing = [p.name for p in s.files if not p.is_file()]
        if missing:
            problems.append(f"{s.name}: data files missing: {missing}")
            continue
        if (n := count(s)) != s.texts:
            problems.append(f"{s.name}: {n} texts, the manifest says {s.texts}")
        if (d := digest(s.folder)) != s.sha256:
            problems.append(f"{s.name}: content hash {d[:16]}…, the manifest says {s.sha256[:16]}…")
    for p in _folder_files(manifest.parent):
        if p != manifest and not any(f in p.parents for f in folders):
            problems.append(f"{p.relative_to(ROOT)}: in no set of the manifest")
    return problems


def write(manifest: Path = MANIFEST) -> int:
    """Rewrite each set's ``texts`` and ``sha256`` lines of the manifest from its files (the rest unchanged)."""
    from jgrounding.io import write_atomic

    text = manifest.read_text()
    sets = load(manifest)
    changed = 0
    for s in sets.values():
        head = f'[sets."{s.name}"]\n'
        start = text.index(head) + len(head)
        end = text.find("\n[", start)
        end = len(text) if end < 0 else end + 1
        body = text[start:end]
        new = re.sub(r"^texts = .*\n", "", body, flags=re.M)
        new = re.sub(r"^sha256 = .*\n", "", new, flags=re.M)
        n = count(s)
        new = new.rstrip("\n") + "\n" + (f"texts = {n}\n" if n is not None else "") + f'sha256 = "{digest(s.folder)}"\n'
        new += "\n" if body.endswith("\n\n") else ""
        changed += new != body
        text = text[:start] + new + text[end:]
    write_atomic(manifest, text)
    load.cache_clear()
    print(f"wrote {manifest.relative_to(ROOT)}: {len(sets)} sets, {changed} changed")
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--write", action="store_true", help="rewrite the manifest's text counts and content hashes")
    args = p.parse_args(argv)
    if args.write:
        return write()
    for s in load().values():
        readers = ", ".join(s.readers) or f"nothing: {s.why}"
        print(f"{s.name:28s} {s.role:6s} {s.texts if s.texts is not None else '-':>6} texts  read by {readers}")
    problems = check()
    print("\n".join(problems) if problems else "every set matches the manifest")
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
