# Two set-up commands for a fresh machine (see README.md):
#   make book   builds the book into _build/html, and its Vietnamese edition into _build/html/vi
#   make test   runs the test suite (library, chapters, and the built site in headless Chromium)
# and make pdf prints the book to _build/pdf/closedloop.pdf (and closedloop.vi.pdf), make course builds
# the course edition (no solutions) into _build/course/html.
# Each creates .venv from the pinned requirements/lock.txt when it is missing or out of date.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# The execution cache notices edits to a notebook's own cells only: a change to the library,
# the lock or the config must re-execute every chapter, so the cache is keyed on this hash too.
# Every .py below src/ and exercises/checking, in subpackages too (find, not a one-level wildcard).
SOURCE_HASH = $(shell cat $$(find src exercises/checking -name '*.py' -not -path '*/__pycache__/*' | LC_ALL=C sort) pyproject.toml requirements/lock.txt _config.yml book/data/benchmark.json book/data/long_runs.json | sha256sum | cut -c1-16)

# Sphinx notices a change to a page or to the config, not to the book's own extensions nor to the files
# they read (the exercises' times and difficulties, the citation): an edit there must rewrite every page
# (but re-executes nothing), so the doctrees are keyed on this hash.
EXTENSIONS_HASH = $(shell cat $$(find book/_ext -name '*.py' | LC_ALL=C sort) exercises/effort.yml CITATION.cff | sha256sum | cut -c1-16)

# The translated editions (book/_ext/editions.py), each from locales/<language>/LC_MESSAGES.
LANGUAGES := vi

# The one version (closedloop.__version__), and the library's wheel that the site offers (book/_ext/companion.py)
VERSION = $(shell sed -n 's/^__version__ = "\(.*\)"$$/\1/p' src/closedloop/__init__.py)
WHEEL = _build/dist/closedloop-$(VERSION)-py3-none-any.whl

.PHONY: book course translations pdf pdf-tools test browser student grade benchmark benchmark-data long-runs-data timings speed clean

# pip byte-compiles every installed module one after another (half of the 50 s an install takes here);
# compileall does the same on every core. It must be done at install: where PYTHONDONTWRITEBYTECODE is
# set (it is here), a module left uncompiled is compiled again by every process that imports it. The
# library's own modules too (0.08 s a process); one edited since is compiled afresh, as always.
$(STAMP): requirements/lock.txt pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-compile -r requirements/lock.txt
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-compile --no-deps --no-build-isolation -e .
	$(BIN)/python -m compileall -q -j 0 "$$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_path("purelib"))')" src >/dev/null
	touch $@

# book and pdf share the execution cache and the doctrees; either clears them, and the pages built
# from them, when the hashes above changed since the last build.
define FRESH_CACHE
@mkdir -p _build
@if [ "$$(cat _build/.source-hash 2>/dev/null)" != "$(SOURCE_HASH)" ]; then \
  rm -rf _build/.jupyter_cache _build/.doctrees _build/html _build/singlehtml _build/course $(addprefix _build/,$(LANGUAGES)); \
  echo "library, lock or config changed since the last build: every chapter is executed afresh"; \
elif [ "$$(cat _build/.extensions-hash 2>/dev/null)" != "$(EXTENSIONS_HASH)" ]; then \
  rm -rf _build/.doctrees _build/html _build/singlehtml _build/course $(addprefix _build/,$(LANGUAGES)); \
  echo "the book's extensions (book/_ext) changed since the last build: every page is written afresh"; \
fi
endef

# One translated edition's build, for book and pdf: $(1) its language (a shell variable in their loops),
# $(2) more options. Its configuration (book/_ext/editions.py) shares the English build's execution cache.
EDITION_BUILD = mkdir -p _build/$(1) && \
  $(BIN)/python book/_ext/editions.py config $(1) > _build/$(1)/_config.yml && \
  $(BIN)/jupyter-book build . -n -W --keep-going --config _build/$(1)/_config.yml --path-output _build/$(1) $(2)

# The library as a wheel, for the site's downloads: pip wheel with the pinned setuptools, from a copy of what
# the wheel is made of (setuptools' build/ and egg-info stay in _build), dated by the last commit.
$(WHEEL): $(STAMP) pyproject.toml README.md LICENSE LICENSE-TEXT $(shell find src -name '*.py' -o -name '*.mplstyle')
	rm -rf _build/dist && mkdir -p _build/dist/source
	tar --exclude=__pycache__ --exclude='*.egg-info' -cf - pyproject.toml README.md LICENSE LICENSE-TEXT src \
	  | tar -xf - -C _build/dist/source
	SOURCE_DATE_EPOCH=$$(git log -1 --format=%ct 2>/dev/null || echo 315532800) \
	  $(BIN)/python -m pip wheel --quiet --disable-pip-version-check --no-deps --no-build-isolation \
	  --wheel-dir _build/dist _build/dist/source
	rm -rf _build/dist/source

book: $(STAMP) $(WHEEL)
	$(FRESH_CACHE)
	@# the pages the execution cache lacks, executed a core each (the build then executes none)
	$(BIN)/python book/_ext/execute_pages.py
	$(BIN)/jupyter-book build . -n -W --keep-going
	@# each translation: the same sources and execution cache (nothing runs twice), its own catalogue
	@for language in $(LANGUAGES); do \
	  $(call EDITION_BUILD,$$language) && \
	  rm -rf _build/html/$$language && cp -r _build/$$language/_build/html _build/html/$$language || exit 1; \
	done
	@echo "$(SOURCE_HASH)" > _build/.source-hash && echo "$(EXTENSIONS_HASH)" > _build/.extensions-hash

# The course edition, for an instructor to publish to a class: the same site without any solution and without
# the instructors' appendix (book/_ext/companion.py), English into _build/course/html, each translation into
# _build/course/html/<language>; from the same execution cache as make book.
COURSE_BUILD = mkdir -p _build/course/$(1) && \
  $(BIN)/python book/_ext/companion.py course-config $(1) > _build/course/$(1)/_config.yml && \
  $(BIN)/jupyter-book build . -n -W --keep-going --config _build/course/$(1)/_config.yml \
    --toc _build/course/_toc.yml --path-output _build/course/$(1)

course: $(STAMP) $(WHEEL)
	$(FRESH_CACHE)
	$(BIN)/python book/_ext/execute_pages.py
	@mkdir -p _build/course && $(BIN)/python book/_ext/companion.py course-toc > _build/course/_toc.yml
	@for language in en $(LANGUAGES); do $(call COURSE_BUILD,$$language) || exit 1; done
	@rm -rf _build/course/html && cp -r _build/course/en/_build/html _build/course/html
	@for language in $(LANGUAGES); do cp -r _build/course/$$language/_build/html _build/course/html/$$language; done
	@echo "$(SOURCE_HASH)" > _build/.source-hash && echo "$(EXTENSIONS_HASH)" > _build/.extensions-hash
	@echo "the course edition: _build/course/html/index.html"

# After editing a page: bring every translation's catalogue in step with the sources (new messages
# empty, changed ones fuzzy), then translate what `tests/test_translations.py` lists.
# (The templates are built in their own folder: a gettext build must not share the site's doctrees;
# and every page is read again, --all, since the book's extensions (book/_ext) decide what is a message.)
translations: $(STAMP)
	@mkdir -p _build/gettext-build
	$(BIN)/python book/_ext/editions.py config en > _build/gettext-build/_config.yml
	$(BIN)/jupyter-book build . -q --all --builder custom --custom-builder gettext \
	  --config _build/gettext-build/_config.yml --path-output _build/gettext-build
	@# the templates' source locations, relative to their folder two levels below this one, as in the catalogues
	find _build/gettext-build/_build/gettext -name '*.pot' -exec sed -i 's|^#: \.\./\.\./\.\./\.\./|#: ../../|; s| \.\./\.\./\.\./\.\./| ../../|g' {} +
	$(BIN)/sphinx-intl update -p _build/gettext-build/_build/gettext -d locales $(foreach language,$(LANGUAGES),-l $(language))

# The book as one PDF: Jupyter Book's single-page build (the same pages and numbering as the site,
# from the same execution cache) printed by Debian's headless Chromium, solutions left out
# (book/print/print_pdf.py; poppler-utils' pdfinfo finds the contents' page numbers).
pdf: $(STAMP) pdf-tools $(WHEEL)
	$(FRESH_CACHE)
	$(BIN)/python book/_ext/execute_pages.py
	$(BIN)/jupyter-book build . --builder singlehtml -n -W --keep-going
	@echo "$(SOURCE_HASH)" > _build/.source-hash && echo "$(EXTENSIONS_HASH)" > _build/.extensions-hash
	@# the English PDF prints while each translation builds its own single page (one after the other, the
	@# steps left the processor idle half the time), then each translation's: _build/pdf/closedloop.<language>.pdf
	@# (a background job starts with SIGINT ignored: a Ctrl-C or SIGTERM that ends the recipe ends it too)
	@$(BIN)/python book/print/print_pdf.py _build/singlehtml _build/pdf/closedloop.pdf & english=$$!; \
	trap 'kill $$english 2>/dev/null' INT TERM; \
	for language in $(LANGUAGES); do \
	  $(call EDITION_BUILD,$$language,--builder singlehtml) && \
	  $(BIN)/python book/print/print_pdf.py _build/$$language/_build/singlehtml _build/pdf/closedloop.$$language.pdf \
	  || { wait $$english; exit 1; }; \
	done; \
	wait $$english

# make pdf needs a browser (below) and poppler-utils; install them when missing (root on CI).
pdf-tools: browser
	@command -v pdfinfo >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq poppler-utils; } >/dev/null 2>&1 \
	  || echo "note: poppler-utils could not be installed here; make pdf needs it"

# The site test and make pdf drive Debian's headless shell of Chromium (book/print/print_pdf.py, chromium());
# install it when missing (root on CI). Debian's whole chromium serves too, at twice the CPU; with neither,
# the site test says so and is skipped.
browser:
	@command -v chromium-headless-shell >/dev/null 2>&1 \
	  || { apt-get update -qq && apt-get install -y -qq chromium-headless-shell; } >/dev/null 2>&1 \
	  || command -v chromium >/dev/null 2>&1 \
	  || echo "note: chromium-headless-shell could not be installed here; the site test and make pdf need it"

test: $(STAMP) browser pdf-tools
	$(BIN)/python -m pytest

# The student version of every exercise notebook (solutions removed), for handing out.
student: $(STAMP)
	$(BIN)/python exercises/make_student.py _build/student

# Grade a class's exercise notebooks (exercises/grade.py): SUBMISSIONS=DIR holds one notebook per student.
# Writes OUT/gradebook.csv and OUT/feedback/ (default _build/grade); CHAPTER=NN when the notebooks do not
# say which chapter; TIMEOUT=seconds for all of one notebook's cells (default 300); JOBS=N at once (default 1).
grade: $(STAMP)
	@test -n "$(SUBMISSIONS)" || { echo "usage: make grade SUBMISSIONS=DIR [CHAPTER=NN] [OUT=DIR] [TIMEOUT=S] [JOBS=N]"; exit 2; }
	$(BIN)/python exercises/grade.py "$(SUBMISSIONS)" $(if $(OUT),--out "$(OUT)") $(if $(CHAPTER),--chapter $(CHAPTER)) \
	  $(if $(TIMEOUT),--timeout $(TIMEOUT)) $(if $(JOBS),--jobs $(JOBS))

# Error against run time of every formulation and method (closedloop.studies.benchmark); prints the tables.
benchmark: $(STAMP)
	$(BIN)/closedloop benchmark

# Regenerate the data file that chapter 8 shows (about 10 minutes); tests/test_benchmark_data.py
# fails until this is run after a change to the library's numerics.
benchmark-data: $(STAMP)
	$(BIN)/closedloop benchmark --json book/data/benchmark.json

# Regenerate the 1000 s runs that chapter 9's study 3 shows (about a minute);
# tests/test_long_runs_data.py fails until this is run after a change to the library's numerics.
long-runs-data: $(STAMP)
	$(BIN)/closedloop long-runs --json book/data/long_runs.json

# Where readers and maintainers wait (issue 14): notebooks' execution, make test from a clean clone,
# the command line, output grids, the basin map; every figure from one run, beside its target (~12 min).
timings: $(STAMP)
	$(BIN)/python benchmarks/timings.py

# The library's best route against the sympy.physics.mechanics baseline at its best, per case.
speed: $(STAMP)
	$(BIN)/python benchmarks/speed_vs_baseline.py

clean:
	rm -rf _build
