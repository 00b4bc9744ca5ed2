#!/usr/bin/env python3
"""Checks that every file, folder, function and type docs/architecture.md
names exists in the tree, so that the page cannot drift from the code.

The rule, for each name the page gives:

* The layout block (the first fenced block of the page): every entry is a
  path - relative to the repository root, or to lib/otmpm/ under the
  "lib/otmpm/" line. "name.*" must match at least one file, "*.cpp" at least
  one file in its folder, "a/" must be a folder; "a.*, b.*" on one line names
  both. The other way round, every .hpp/.cpp file of lib/otmpm/ must be in
  the layout: named by an entry (its path, "stem.*", a glob), by its file
  name in the text of an entry of its folder (elastic.cpp), or by its stem
  in the text of its folder's entry ("distributed/ ... comm, halo ...").
* Prose, `backticked`: a token with a '/' or a file extension (.hpp, .cpp,
  .py, .sh, .toml, .md, .txt) and no '(', '=' or '-' is a path; it must
  exist relative to the root, to lib/otmpm/ or to tests/, or be the end of a
  path in the tree (a sentence may give only a folder's last part). A word
  of capitals is a placeholder for any name (`integrators/NAME.cpp`).
* Prose, `backticked`, code-like: a C++ name with '::', '<...>', '(...)',
  a capital letter or an underscore (`Engine<D>`, `fill_basis_table`,
  `Basis::evaluate_points(x, table, &F)`): every identifier of its qualified
  name (before '<' and '(') must occur in the code - lib/, drivers/,
  python/src/, python/otmpm/, scripts/ - with comments removed (C++ '//' and
  '/* */', Python and shell '#'). A name that only a comment still mentions
  does not count. Python's builtins (`MemoryError`) and symbols with a
  subscript (`w_I`, `x_p`) are not looked up. Tokens that are formulas, scene keys or values (`x_I +=
  dx_I`, `mode = "mpm"`, `output.fields`, `det F <= 0`) are not names: they
  contain spaces, '=', '.' outside a path, or nothing code-like.

* The other fenced blocks (the data flow of a step): every word with an
  underscore is a stage or field and must occur in the code as above,
  except symbols with a subscript of up to three characters (`x_p`, `N_Ip`);
  `name_*` stands for any word that starts with `name_`.

Exit status 1 with one line per missing name."""
import builtins
import os
import re
import sys

root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
page = os.path.join(root, "docs", "architecture.md")
text = open(page, encoding="utf-8").read()
missing = []

# ---------------------------------------------------------------- the tree
tree = []
for d, dirs, names in os.walk(root):
    dirs[:] = [x for x in dirs if not x.startswith(".") and not x.startswith("build") and x != "__pycache__"]
    rel = os.path.relpath(d, root)
    for n in names:
        tree.append(os.path.normpath(os.path.join(rel, n)))
folders = {os.path.dirname(p) for p in tree}
folders |= {os.path.dirname(f) for f in folders}


def path_exists(p, bases=("", "lib/otmpm", "tests")):
    p = p.rstrip("/")
    for b in bases:
        q = os.path.normpath(os.path.join(b, p))
        if "*" in q:
            rx = re.compile("^" + re.escape(q).replace(r"\*", "[^/]*") + "$")
            if any(rx.match(t) for t in tree):
                return True
        elif q in tree or q in folders:
            return True
    return False


# ---------------------------------------------------------------- the code
def strip_comments(src, python_like):
    if python_like:
        return re.sub(r"(?m)(^|\s)#(?![!]).*$", r"\1", src)
    src = re.sub(r"/\*.*?\*/", " ", src, flags=re.S)
    return re.sub(r"//.*", "", src)


code_words = set()
for p in tree:
    top = p.split(os.sep)[0]
    if top not in ("lib", "drivers", "python", "scripts"):
        continue
    if top == "python" and not (p.startswith("python/src/") or p.startswith("python/otmpm/")):
        continue
    if not p.endswith((".hpp", ".cpp", ".h", ".py", ".sh")):
        continue
    src = open(os.path.join(root, p), encoding="utf-8", errors="replace").read()
    code_words |= set(re.findall(r"[A-Za-z_~][A-Za-z0-9_]*", strip_comments(src, not p.endswith((".hpp", ".cpp", ".h")))))

# ---------------------------------------------------------------- the layout block
# An entry line starts at indent 0 (the root) or 2 (under lib/otmpm/); deeper
# lines continue the entry above. The entry's paths are its leading tokens
# with '/', '.' or '*'; one without '/' shares the folder of the one before.
layout = []  # (folder, [paths], text of the entry)
base = ""
for line in re.findall(r"```\n(.*?)```", text, flags=re.S)[0].splitlines():
    indent = len(line) - len(line.lstrip())
    if not line.strip():
        continue
    if indent >= 4 and layout:
        layout[-1][2] += " " + line.strip()
        continue
    if indent == 0:
        base = ""
    paths, folder = [], None
    for token in line.split():
        item = token.rstrip(",")
        if not re.fullmatch(r"[A-Za-z0-9_.*/+-]+", item) or not re.search(r"[/.*]", item):
            break
        if "/" not in item.rstrip("/") and folder:
            item = folder + "/" + item
        folder = os.path.dirname(item.rstrip("/"))
        paths.append(item)
        if not token.endswith(","):
            break
    if paths == ["lib/otmpm/"]:
        base = "lib/otmpm"
        continue
    layout.append([base, paths, line.strip()])
    for item in paths:
        if not path_exists(item, (base,)):
            missing.append(f"layout: '{item}' (under {base or 'the root'}) does not exist")

# Every file of lib/otmpm/ is in the layout: an entry names it (a.hpp, a.*,
# *.cpp, a_*), or names its folder and, in its text, the file's stem.
for p in tree:
    if not p.startswith("lib/otmpm/") or not p.endswith((".hpp", ".cpp")):
        continue
    rel = os.path.relpath(p, "lib/otmpm")
    stem = os.path.splitext(os.path.basename(rel))[0]
    covered = False
    for b, paths, entry in layout:
        if b != "lib/otmpm":
            continue
        for item in paths:
            if item.endswith("/") and os.path.dirname(rel) == item.rstrip("/"):
                covered = covered or re.search(rf"\b{re.escape(stem)}\b", entry) is not None
            elif re.fullmatch(re.escape(item).replace(r"\*", "[^/]*"), rel):
                covered = True
        if not covered and os.path.dirname(rel) in {os.path.dirname(i) for i in paths}:
            covered = re.search(rf"\b{re.escape(os.path.basename(rel))}\b", entry) is not None
    if not covered:
        missing.append(f"layout: lib/otmpm/{rel} is not in the layout")

# ---------------------------------------------------------------- prose
prose = re.sub(r"```.*?```", "", text, flags=re.S)
extension = re.compile(r"\.(hpp|cpp|py|sh|toml|md|txt|h5)$")
name = re.compile(r"^[A-Za-z_~][A-Za-z0-9_]*(::[A-Za-z_~][A-Za-z0-9_]*)*(<[^<>]*>)?(\(.*\))?$")
for token in sorted(set(re.findall(r"`([^`\n]+)`", prose))):
    t = token.strip()
    if (("/" in t and " " not in t) or extension.search(t)) and not re.search(r"[()=-]", t):
        t = re.sub(r"\b[A-Z]{3,}\b", "*", t)  # a placeholder: integrators/NAME.cpp
        tail = re.compile("(^|/)" + re.escape(t.rstrip("/")).replace(r"\*", "[^/]*") + "$")
        if not (path_exists(t) or any(tail.search(p) for p in tree)):
            missing.append(f"prose: path `{t}` does not exist")
        continue
    if not name.match(t):
        continue
    qualified = re.split(r"[<(]", t, maxsplit=1)[0]
    if hasattr(builtins, qualified) or re.fullmatch(r"[A-Za-z]_[A-Za-z0-9]{1,2}", qualified):
        continue  # a Python builtin (MemoryError), a symbol with a subscript (w_I)
    if not ("::" in t or "<" in t or "(" in t or "_" in qualified or re.search(r"[A-Z]", qualified)):
        continue
    for part in qualified.split("::"):
        if part not in code_words:
            missing.append(f"prose: `{t}`: '{part}' does not occur in the code")
# ---------------------------------------------------------------- the other fenced blocks
# (data flow of a step, a distributed step): every word with an underscore
# names a stage or field of the code, except symbols with a subscript (x_p,
# N_Ip); "name_*" is any code word that starts with "name_".
for block in re.findall(r"```\n(.*?)```", text, flags=re.S)[1:]:
    for word in sorted(set(re.findall(r"\b[A-Za-z][A-Za-z0-9]*_[A-Za-z0-9_]*\*?", block))):
        if re.fullmatch(r"[A-Za-z]{1,4}_[A-Za-z0-9]{1,3}", word):
            continue
        ok = any(w.startswith(word[:-1]) for w in code_words) if word.endswith("*") else word in code_words
        if not ok:
            missing.append(f"block: '{word}' does not occur in the code")

for line in missing:
    print(line)
print(f"{len(missing)} name(s) of docs/architecture.md missing from the tree" if missing
      else "every name of docs/architecture.md exists")
sys.exit(1 if missing else 0)
