"""The CLI's pictures name the text and the tuple it grounded to (or the tuple alone when it was given)."""

from jgrounding.apps.cli import build_parser, picture_title


def test_the_title_names_the_text_and_the_tuple():
    assert picture_title("User seems sad;\n respond calmly", "comforting", "moderate") == (
        '"User seems sad; respond calmly" -> (comforting, moderate)'
    )
    assert picture_title(None, "nodding", "subtle") == "(nodding, subtle)"
    long = picture_title("x" * 100, "nodding", "subtle", width=20)
    assert long.startswith('"' + "x" * 19 + '…"') and long.endswith("(nodding, subtle)")
    assert "not acted on" in picture_title("hm", "nodding", "subtle", hold=True)


def test_help_says_where_the_files_go():
    text = " ".join(build_parser().format_help().split())
    assert "default grounding_out/" in text and "--jsonl" in text
