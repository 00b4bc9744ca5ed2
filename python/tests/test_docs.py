"""Every `>>>` session of docs/python.md, run again and compared with the
output the page shows (doctest; `...` matches what changes from run to run).
The sessions run in order in one namespace, in a fresh folder holding a link
`examples` to the repository's examples/."""
import doctest
import os
import re

from conftest import SOURCE


def sessions(path):
    """The contents of the ```pycon blocks of a markdown file, in order, as one text."""
    with open(path) as f:
        return "\n".join(re.findall(r"^```pycon\n(.*?)^```", f.read(), flags=re.S | re.M))


def test_docs_python_md(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.symlink(SOURCE / "examples", tmp_path / "examples")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    text = sessions(SOURCE / "docs" / "python.md")
    test = doctest.DocTestParser().get_doctest(text, {}, "docs/python.md", str(SOURCE / "docs" / "python.md"), 0)
    assert len(test.examples) > 60
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.failures == 0, f"{runner.failures} of {runner.tries} examples of docs/python.md failed (see above)"
