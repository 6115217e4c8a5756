"""The Vietnamese edition's catalogues (``locales/vi/LC_MESSAGES``): complete, in step, true to the glossary.

The checks themselves are in ``book/_ext/translations.py`` (translators run them on their own files);
here they run over every catalogue, and each failure lists what is wrong, file by file. The built
Vietnamese pages are read by tests/test_site.py (in Chromium) and at the end of this file.
"""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

from ._toc import toc_pages, toc_parts

ROOT = Path(__file__).resolve().parents[1]
LOCALE = ROOT / "locales" / "vi" / "LC_MESSAGES"
UPDATE = "make translations"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "book" / "_ext" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module                      # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


translations = _load("translations")


@pytest.fixture(scope="module")
def all_problems():
    terms = translations.glossary_terms()
    interface = LOCALE / f"{translations.INTERFACE}.po"
    return [problem for path in [*translations.catalogues(LOCALE).values(), interface]
            for problem in translations.problems(path, terms)]


def by_file(problems):
    listing = {}
    for problem in problems:
        listing.setdefault(Path(problem.path).relative_to(LOCALE).as_posix(), []).append(
            f"line {problem.line}: {problem.msgid[:80]!r}")
    return listing


def test_every_page_has_a_catalogue():
    assert set(translations.catalogues(LOCALE)) == set(toc_pages()), f"run `{UPDATE}`"


def test_every_message_is_translated(all_problems):
    missing = [p for p in all_problems if p.reason == "not translated" or p.reason.startswith("fuzzy")]
    assert by_file(missing) == {}, "untranslated or fuzzy messages, by file"


def test_translations_keep_the_markup(all_problems):
    changed = [str(p) for p in all_problems if p.reason.startswith("markup changed")]
    assert changed == []


def test_each_glossary_term_has_one_vietnamese_form(all_problems):
    """Wherever the English names a glossary term, the Vietnamese uses the glossary's form of it."""
    astray = [str(p) for p in all_problems if p.reason.startswith("the glossary's")]
    assert astray == []


def test_the_glossary_lists_the_papers_terms():
    """The terms the paper itself uses for the book's key ideas are glossary entries (issue 13's list)."""
    terms = {translations.normal(term.vietnamese) for term in translations.glossary_terms()}
    paper = ["phương trình Lagrange dạng nhân tử", "phương trình vi phân - đại số", "ổn định hóa Baumgarte",
             "định lý trực giao", "tọa độ suy rộng dư", "cơ cấu tay quay – con trượt", "điều kiện đầu",
             "chuyển động quay toàn vòng", "khâu dẫn", "con trượt", "thanh truyền"]
    assert [term for term in paper if translations.normal(term) not in terms] == []


# --- the checker itself can fail --------------------------------------------------------------

def test_the_markup_check_sees_a_changed_target():
    source = "See {ref}`the first case <case-1>`, [(32)](eq-32), `simulate` and $\\varphi_0$ {cite}`khang2018`."
    kept = "Xem {ref}`trường hợp đầu <case-1>`, [(32)](eq-32), `simulate` và $\\varphi_0$ {cite}`khang2018`."
    assert translations.markup(source) == translations.markup(kept)
    for broken in (kept.replace("<case-1>", "<case-2>"), kept.replace("`simulate`", "simulate"),
                   kept.replace("(eq-32)", "(eq-23)"), kept.replace("$\\varphi_0$", "$\\varphi$"),
                   kept.replace("khang2018", "khang")):
        assert translations.markup(source) != translations.markup(broken), broken


def test_the_glossary_check_sees_a_synonym(tmp_path):
    catalogue = tmp_path / "page.po"
    catalogue.write_text('msgid ""\nmsgstr ""\n"Content-Type: text/plain; charset=UTF-8\\n"\n\n'
                         'msgid "The initial conditions of case 1."\nmsgstr "Các điều kiện ban đầu của trường hợp 1."\n\n'
                         'msgid "The crank turns."\nmsgstr "Tay quay quay."\n\n'
                         'msgid "A link to the licence."\nmsgstr "Một đường dẫn tới giấy phép."\n\n'
                         'msgid "Every other link turns."\nmsgstr "Mọi thanh khác đều quay."\n\n'
                         'msgid "A new page."\nmsgstr ""\n', encoding="utf-8")
    found = translations.problems(catalogue)
    assert [(p.msgid, p.reason.split(":")[0]) for p in found] == [
        ("The initial conditions of case 1.", "the glossary's 'điều kiện đầu' for 'initial conditions' is not used"),
        ("Every other link turns.", "the glossary's 'khâu' for 'link' is not used"),
        ("A new page.", "not translated")]


def test_out_of_step_names_the_page_that_changed(tmp_path):
    templates, locale = tmp_path / "pot", tmp_path / "po"
    for folder, text in ((templates, "Old words."), (locale, "Old words.")):
        (folder / "chapters").mkdir(parents=True)
        (folder / "chapters" / ("a.pot" if folder == templates else "a.po")).write_text(
            f'msgid "{text}"\nmsgstr ""\n', encoding="utf-8")
    assert translations.out_of_step(templates, locale) == {}
    (templates / "chapters" / "a.pot").write_text('msgid "New words."\nmsgstr ""\n', encoding="utf-8")
    (templates / "chapters" / "b.pot").write_text('msgid "A page."\nmsgstr ""\n', encoding="utf-8")
    assert translations.out_of_step(templates, locale) == {
        "chapters/a": "1 new message(s), 1 no longer in the source", "chapters/b": "no catalogue"}


# --- against the sources and the built edition -------------------------------------------------

def test_catalogues_are_in_step_with_the_sources(built_site):
    """A page edited without updating the catalogues fails here, naming the command that updates them."""
    import yaml

    editions = _load("editions")
    folder = ROOT / "_build" / "gettext-test"            # not make translations' folder: never in its way
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "_config.yml").write_text(yaml.safe_dump(editions.edition_config("en"), allow_unicode=True))
    jupyter_book = Path(sys.executable).with_name("jupyter-book")
    run = subprocess.run([str(jupyter_book), "build", ".", "-q", "--all", "--builder", "custom", "--custom-builder", "gettext",
                          "--config", str(folder / "_config.yml"), "--path-output", str(folder)],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    differ = translations.out_of_step(folder / "_build" / "gettext", LOCALE)
    assert differ == {}, (f"the Vietnamese catalogues are out of step with the sources: run `{UPDATE}`, "
                          "then translate what test_every_message_is_translated lists")


def test_the_vietnamese_pages_are_vietnamese(built_site):
    """Every built Vietnamese page says it is Vietnamese, and its prose is: outside code, outputs, math,
    bold glossary terms, citations and the library reference's docstrings (English in both editions),
    no paragraph, heading or title reads as English (two or more
    English function words, such as "the", "of", "which", making up a tenth of its words). The
    words are ones no Vietnamese syllable spells ("in", "to", "an" are Vietnamese words too). And the
    site around each page (the theme's words, the links beside headings, the search box, the code
    cells' buttons) shows none of the English page's words there."""
    from bs4 import BeautifulSoup

    english = {"the", "of", "and", "is", "that", "with", "for", "are", "this", "its", "from", "which", "or",
               "not", "each", "what", "when", "where", "was", "were", "has", "have", "been"}
    captions = {part["caption"] for part in toc_parts()}
    pages = [page for page in toc_pages() if page != "book/bibliography"]
    front = BeautifulSoup((built_site / "vi" / "index.html").read_text(encoding="utf-8"), "html.parser")
    assert front.html.get("lang") == "vi", "the front page (index.html, which sends the reader on)"
    found = {}
    for page in pages:
        soup = BeautifulSoup((built_site / "vi" / f"{page}.html").read_text(encoding="utf-8"), "html.parser")
        assert soup.html.get("lang") == "vi", page
        shown = {caption.get_text(" ").strip() for caption in soup.select(".caption-text")}
        assert shown and not shown & captions, f"{page}: the table of contents' captions are English"
        article = soup.select_one("article")
        for skip in article.select("div.cell_output, div.highlight, pre, code, .math, span.math, div.math, "
                                   "a.reference.internal[href*=bibliography], .edition-links, strong, dt, "
                                   ".docstring, dl.py"):
            skip.decompose()
        footer = soup.select_one("footer")
        for block in article.select("p, li, h1, h2, h3, caption, figcaption, dd") + (footer.select("p") if footer else []):
            words = re.findall(r"[^\W\d_]+", block.get_text(" "))
            hits = sum(word in english for word in words)
            if hits >= 2 and hits >= 0.1 * len(words):
                found.setdefault(page, []).append(block.get_text(" ")[:100])
    assert found == {}, "paragraphs of the Vietnamese edition that read as English"
    for page in [*pages, "search", "genindex"]:
        same = (interface_words((built_site / f"{page}.html").read_text(encoding="utf-8"))
                & interface_words((built_site / "vi" / f"{page}.html").read_text(encoding="utf-8"))) - NOT_WORDS
        if same:
            found[page] = sorted(same)
    assert found == {}, "the site's words around the pages left in English (locales/vi/LC_MESSAGES/sphinx.po)"


#: Interface texts the same in both editions by right: a key's name, file types, file names, a unit.
NOT_WORDS = {"Ctrl", ".ipynb", ".md", ".pdf", "LICENSE", "LICENSE-TEXT", "html", "rad/s"}


def interface_words(page_html):
    """The words of the site around a page's content: the theme's and Sphinx's text outside the article,
    the foot of the page, the code cells' buttons, and every ``title``, ``aria-label``, ``placeholder``
    and ``data-bs-title`` (outside outputs and citations, which are another test's and English by right,
    and code: the names of the library reference's entries in the page's contents)."""
    from bs4 import BeautifulSoup, Comment

    soup = BeautifulSoup(page_html, "html.parser")
    for node in soup(["script", "style"]):
        node.decompose()
    for node in soup.find_all(string=lambda text: isinstance(text, Comment)):
        node.extract()
    for node in soup.select("div.cell_output, a[href*='bibliography'], .edition-links, .math, pre, code"):
        node.decompose()
    words = {node[name].strip() for node in soup.find_all(True)
             for name in ("title", "aria-label", "placeholder", "data-bs-title") if node.has_attr(name)}
    article = soup.select_one("article")
    if article is not None:
        for node in article.select("summary, .prev-next-area"):
            words.update(text.strip() for text in node.find_all(string=True))
        article.extract()
    words.update(text.strip() for text in soup.find_all(string=True))
    # (a link's title that names an object of the library, "closedloop.simulate", is code, not a word)
    return {word for word in words if re.search(r"[A-Za-z]{2}", word) and not re.fullmatch(r"closedloop(\.\w+)+", word)}


def test_the_interface_check_sees_an_english_word():
    page = ('<html><body><nav aria-label="Site navigation"><a title="Index">x</a></nav><article>'
            '<p title="Trích dẫn">Văn bản</p><details><summary aria-label="Toggle hidden content">'
            '<p>Show code cell source</p></summary></details><div class="cell_output"><img alt="A"></div>'
            '</article><footer>Back to top</footer><!-- a comment --></body></html>')
    assert interface_words(page) == {"Site navigation", "Index", "Trích dẫn", "Toggle hidden content",
                                     "Show code cell source", "Back to top"}


def test_every_page_shows_the_same_display_equations_in_both_editions(built_site):
    """Each page's display equations, in the order the page shows them, are those of the English page:
    as many, the same TeX outside the words of ``\\text{}``, none empty and none ``::`` (what a
    translated equation became when Sphinx parsed its msgstr as reStructuredText, issue 36)."""
    differ = {}
    for page in toc_pages():
        english = translations.display_equations((built_site / f"{page}.html").read_text(encoding="utf-8"))
        vietnamese = translations.display_equations((built_site / "vi" / f"{page}.html").read_text(encoding="utf-8"))
        broken = [tex for tex in vietnamese if tex in ("", "::")]
        if broken or english != vietnamese:
            differ[page] = (f"{len(english)} equations in English, {len(vietnamese)} in Vietnamese, "
                            f"{len(broken)} empty or '::'; first difference: "
                            f"{next(((e, v) for e, v in zip(english, vietnamese) if e != v), None)}")
    assert differ == {}


def test_the_equation_comparison_sees_a_lost_equation():
    page = ('<div class="math">\\[\na = b \\qquad\\text{or}\\qquad c = d\n\\]</div>'
            '<div class="math">\\[::\\]</div>')
    assert translations.display_equations(page) == ["a = b \\qquad\\text{}\\qquad c = d", "::"]
    translated = page.replace("\\text{or}", "\\text{hoặc}")
    assert translations.display_equations(translated) == translations.display_equations(page)


def output_words(page_html):
    """The words a reader meets in a built page's code-cell outputs, in order: the headings and captions
    of tables, the labels of the animations' player, every alt, title and aria-label."""
    from bs4 import BeautifulSoup

    soup = BeautifulSoup(page_html, "html.parser")
    words = []
    for output in soup.select("article div.cell_output"):
        for script in output.select("script, style"):
            script.decompose()
        for link in output.select("a.headerlink"):      # Sphinx's own link beside a figure: the interface's
            link.decompose()
        for node in output.find_all(True):
            if node.name in ("th", "caption", "label"):
                words.append(node.get_text().strip())
            words += [node[name].strip() for name in ("alt", "title", "aria-label") if node.has_attr(name)]
    return [word for word in words if re.search(r"[^\W\d_]{2}", word)]


def test_the_words_of_the_outputs_are_translated(built_site):
    """The editions share one execution, so their outputs are English; the Vietnamese pages show the
    catalogue's translation of every heading, alt text and player label of them (book/_ext/translatable.py),
    and the code cells' buttons in Vietnamese."""
    translatable = _load("translatable")
    wrong, buttons = {}, {}
    for page in toc_pages():
        english = output_words((built_site / f"{page}.html").read_text(encoding="utf-8"))
        vietnamese_html = (built_site / "vi" / f"{page}.html").read_text(encoding="utf-8")
        vietnamese = output_words(vietnamese_html)
        catalogue = {message.id: message.string for message in translations.read_catalog(LOCALE / f"{page}.po")
                     if message.id and message.string and not message.fuzzy}
        # a figure's alt text is a message as it stands (Sphinx's own); an HTML output's words have their
        # numbers as parameters
        expected = [catalogue.get(word) or translatable.localised(word, catalogue.get) for word in english]
        shown = [(word, wanted, seen) for word, wanted, seen in zip(english, expected, vietnamese) if seen != wanted]
        # a word the extension does not read is in no catalogue, and would pass the comparison untranslated
        # (a heading of mathematics and a unit alone, "\\(m_i\\) [kg]", has no word to read)
        unread = [word for word in english if word not in catalogue and translatable.message_of(word)[0] not in catalogue
                  and re.search(r"[^\W\d_]{3}", re.sub(r"\\\(.*?\\\)", " ", word))]
        if len(english) != len(vietnamese) or shown or unread:
            wrong[page] = (len(english), len(vietnamese), shown[:3], unread[:3])
        left = re.findall(r"(?:Show|Hide) code cell \w+", vietnamese_html)
        if left:
            buttons[page] = sorted(set(left))
    assert wrong == {}, ("pages whose outputs' words are not the catalogue's: (count, count, first mismatches, "
                         "first words in no catalogue)")
    assert buttons == {}, "English buttons of code cells on Vietnamese pages"


def pasted_words(page_html):
    """The words a ``{glue:text}`` role pasted into a built page's prose (MyST-NB's ``span.pasted-text``),
    in order: the pastes that hold a word, not a number alone."""
    from bs4 import BeautifulSoup

    spans = BeautifulSoup(page_html, "html.parser").select("article span.pasted-text")
    return [text for text in (span.get_text() for span in spans) if re.search(r"[^\W\d_]{2,}", text)]


def test_the_words_pasted_into_the_prose_are_translated(built_site):
    """A sentence's words that a glue role pastes from the shared English execution ("in three of the
    four cases", "RK45 or DOP853") are shown in Vietnamese on the Vietnamese page: each is a message of
    the page's catalogue (its numbers parameters), translated, and put in place."""
    translatable = _load("translatable")
    wrong, pasted = {}, 0
    for page in toc_pages():
        english = pasted_words((built_site / f"{page}.html").read_text(encoding="utf-8"))
        vietnamese = pasted_words((built_site / "vi" / f"{page}.html").read_text(encoding="utf-8"))
        catalogue = {message.id: message.string for message in translations.read_catalog(LOCALE / f"{page}.po")
                     if message.id and message.string and not message.fuzzy}
        pasted += len(english)
        missing = [word for word in english if translatable.message_of(word)[0] not in catalogue]
        expected = [translatable.localised(word, catalogue.get) for word in english]
        if missing or expected != vietnamese:
            wrong[page] = (missing[:3], [(e, v) for e, v in zip(expected, vietnamese) if e != v][:3],
                           len(english), len(vietnamese))
    assert pasted > 5, "the test reads no pasted words: has MyST-NB's class for them changed?"
    assert wrong == {}, "pages whose pasted words are in no catalogue, or not shown translated: (missing, shown)"


def test_the_output_words_are_read_and_put_back():
    """The extension finds the words of an HTML output and puts a translation back in their place only."""
    translatable = _load("translatable")
    html = ('<table class="closedloop-table"><thead><tr><th class="num">max |f| [m]</th><th>case</th></tr>'
            '</thead><tbody><tr><td>case</td></tr></tbody></table><img alt="A &quot;flat&quot; line">'
            '<button title="Play" aria-label="Play"></button><label for="r">Once</label>'
            '<label><input type="radio" value="loop"><span>Loop</span></label><script>var title="Play";</script>')
    assert translatable.html_messages(html) == ["max |f| [m]", "case", 'A "flat" line', "Play", "Once", "Loop"]
    node = translatable.translated_html(html, html, format="html")
    node.preserve_original_messages()
    node.apply_translated_message("case", "trường hợp")
    node.apply_translated_message("Play", "Phát")
    node.apply_translated_message('A "flat" line', 'Một đường "phẳng"')
    node.apply_translated_message("Loop", "Lặp lại")
    assert node.astext() == html.replace("<th>case</th>", "<th>trường hợp</th>").replace(
        '"Play" aria-label="Play"', '"Phát" aria-label="Phát"').replace(
        "A &quot;flat&quot; line", "Một đường &quot;phẳng&quot;").replace("<span>Loop</span>", "<span>Lặp lại</span>")
    assert node.extract_original_messages() == ["max |f| [m]", "case", 'A "flat" line', "Play", "Once", "Loop"]
    numbered = translatable.translated_html("", '<th>rtol = 1e-06</th><th>rtol = 1e-09</th>', format="html")
    numbered.preserve_original_messages()
    assert numbered.extract_original_messages() == ["rtol = {1}"]            # one message for both values
    numbered.apply_translated_message("rtol = {1}", "dung sai {1}")
    assert numbered.astext() == "<th>dung sai 1e-06</th><th>dung sai 1e-09</th>"
