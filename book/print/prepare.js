// Turns the single-page build of the book into the page that print_pdf.py prints.
// Called once, after MathJax and BokehJS have drawn everything, as page.evaluate(this, texts);
// returns what it changed, counted, for the script's report. Changes only the DOM; the look is in
// print.css.
(texts) => {
  const article = document.querySelector('article.bd-article');
  const counts = {};

  // The chapter (or exercise page) that holds an element: the last document start before it.
  const starts = [...article.querySelectorAll('span[id^="document-"]')];
  const documentOf = (element) => {
    let found = null;
    for (const start of starts) {
      if (start.compareDocumentPosition(element) & Node.DOCUMENT_POSITION_FOLLOWING) found = start;
    }
    return found;
  };
  const chapterNumber = (start) => {
    const number = start && start.nextElementSibling &&
      start.nextElementSibling.querySelector(':scope > h2 .section-number');
    return number ? number.textContent.trim().replace(/\.$/, '') : '';
  };
  const note = (template, element) => {
    const paragraph = document.createElement('p');
    paragraph.className = 'pdf-note';
    paragraph.textContent = template.replace('{chapter}', chapterNumber(documentOf(element)));
    return paragraph;
  };

  // The pages for instructors only (the rubrics) out, with their entries in the contents below: the
  // PDF is handed out, as the course edition is published.
  const omitted = new Set((texts.omit || []).map((docname) => 'document-' + docname));
  omitted.forEach((id) => {
    const start = document.getElementById(id);
    if (!start) return;
    if (start.nextElementSibling) start.nextElementSibling.remove();
    start.remove();
  });
  counts.omittedPages = omitted.size;

  // Every solution out: sphinx-exercise's {solution} and the gated solution-start/solution-end,
  // both a div.solution holding all that the solution shows (its code cells too).
  const solutions = [...article.querySelectorAll('div.solution')];
  solutions.forEach((solution) => solution.remove());
  counts.solutions = solutions.length;

  // Cells tagged hide-input print as the site shows them first: without the code. An output
  // tagged hide-output is printed (the text reads it; there is nothing to click on paper).
  const hiddenInputs = [...article.querySelectorAll('details.hide.above-input')];
  hiddenInputs.forEach((details) => details.remove());
  counts.hiddenInputs = hiddenInputs.length;
  const hiddenOutputs = [...article.querySelectorAll('details.hide.below-input')];
  hiddenOutputs.forEach((details) => {
    [...details.children].filter((child) => child.tagName !== 'SUMMARY')
      .forEach((child) => details.before(child));
    details.remove();
  });
  counts.hiddenOutputs = hiddenOutputs.length;
  // Any other dropdown (sphinx-togglebutton) open, without its button.
  article.querySelectorAll('.toggle-hidden').forEach((e) => e.classList.remove('toggle-hidden'));
  article.querySelectorAll('button.toggle-button').forEach((button) => button.remove());
  article.querySelectorAll('details').forEach((details) => { details.open = true; });

  // Animations (the player of closedloop.plotting.player): the frame on show, no controls.
  const animations = [...article.querySelectorAll('div.animation')];
  animations.forEach((animation) => {
    animation.querySelectorAll('.anim-controls').forEach((controls) => controls.remove());
    animation.classList.add('pdf-still');
    animation.after(note(texts.animation, animation));
  });
  counts.animations = animations.length;

  // Interactive Bokeh figures (closedloop.plotting.interactive): drawn, toolbars hidden, a note.
  if (window.Bokeh) {
    for (const doc of Bokeh.documents) {
      for (const model of doc.all_models) {
        if ('autohide' in model && 'tools' in model) model.autohide = true;
      }
    }
  }
  const figures = [...article.querySelectorAll('div.closedloop-bokeh')];
  figures.forEach((figure) => figure.after(note(texts.interactive, figure)));
  counts.interactive = figures.length;

  // Links within the book point into this page (Sphinx's single page writes some as
  // "book/intro.html#label", relative to the wrong folder); no link leads to another local file.
  let links = 0;
  article.querySelectorAll('a[href]').forEach((a) => {
    const url = new URL(a.getAttribute('href'), location.href);
    if (url.origin !== location.origin) return;
    if (url.hash) {
      a.setAttribute('href', url.hash);
    } else {
      a.replaceWith(...a.childNodes);
    }
    links += 1;
  });
  counts.internalLinks = links;

  // The theme's own print block (title and contents) gives way to a title page and a contents
  // with page numbers; the part captions of the contents also head each part in the text.
  const themeBlock = document.getElementById('jb-print-docs-body');
  const toc = themeBlock.querySelector('#jb-print-toc nav');
  const front = document.createElement('section');
  front.id = 'pdf-front';
  const titlePage = document.createElement('div');
  titlePage.className = 'pdf-title-page';
  const title = document.createElement('p');
  title.className = 'pdf-title';
  title.textContent = document.title;
  titlePage.append(title);
  // The citation and the downloads, from the page's <meta> tags (book/_ext/companion.py).
  const meta = (name) => {
    const found = document.querySelector(`meta[name="${name}"]`);
    return found ? found.getAttribute('content') : '';
  };
  const fill = (template) => template.replace(/\{(\w+)\}/g, (_, key) => meta('closedloop:' + key));
  const line = (className, text) => {
    const paragraph = document.createElement('p');
    paragraph.className = className;
    paragraph.textContent = text;
    titlePage.append(paragraph);
  };
  line('pdf-author', meta('citation_author'));
  line('pdf-version', fill(texts.version));
  line('pdf-downloads', fill(texts.downloads));
  if (meta('closedloop:repository')) line('pdf-downloads', fill(texts.repository));
  const licence = document.querySelector('.extra_footer');
  if (licence) {
    const small = document.createElement('div');
    small.className = 'pdf-licence';
    small.innerHTML = licence.innerHTML;
    titlePage.append(small);
  }
  const contents = document.createElement('nav');
  contents.id = 'pdf-contents';
  const heading = document.createElement('h1');
  heading.textContent = themeBlock.querySelector('#jb-print-toc h2').textContent.trim();
  contents.append(heading);
  let entries = 0;
  let part = null;
  for (const item of toc.children) {
    if (item.matches('p.caption')) {
      part = item.textContent.trim();
      const row = document.createElement('p');
      row.className = 'pdf-toc-part';
      row.textContent = part;
      contents.append(row);
      continue;
    }
    item.querySelectorAll('a[href^="#document-"]').forEach((a, index) => {
      const target = a.getAttribute('href').slice(1);
      if (omitted.has(target)) return;
      const row = document.createElement('a');
      row.className = 'pdf-toc-entry';
      row.href = '#' + target;
      const text = document.createElement('span');
      text.className = 'pdf-toc-title';
      text.textContent = a.textContent.trim();
      const page = document.createElement('span');
      page.className = 'pdf-toc-page';
      page.dataset.target = target;
      page.textContent = '000';                 // the first print's placeholder, as wide as a number
      const leader = document.createElement('span');
      leader.className = 'pdf-toc-leader';
      row.append(text, leader, page);
      contents.append(row);
      entries += 1;
      const start = document.getElementById(target);
      if (index === 0 && part && start) {       // the part's name above its first page's title
        const partHeading = document.createElement('h1');
        partHeading.className = 'pdf-part';
        partHeading.textContent = part;
        start.nextElementSibling.prepend(partHeading);
      }
    });
  }
  counts.contentsEntries = entries;
  front.append(titlePage, contents);
  themeBlock.remove();
  article.before(front);
  return counts;
}
