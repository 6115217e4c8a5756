"""Switch Thebe off: this book never runs code in the page.

Jupyter Book 1.x always loads sphinx-thebe. Under Sphinx 7 its inline config script
(``const THEBE_JS_URL = ...``) lands in every page twice, and the second copy is a
JavaScript error ("Identifier 'THEBE_JS_URL' has already been declared"). This
extension disconnects sphinx-thebe's page work (the config script, its loader and
the per-page kernel settings) and drops its stylesheet, so no page carries any of it.
"""

THEBE_HANDLERS = {"init_thebe_core", "update_thebe_context"}


def setup(app):
    app.setup_extension("sphinx_thebe")
    for listeners in app.events.listeners.values():
        for listener in list(listeners):
            handler = listener.handler
            if handler.__module__ == "sphinx_thebe" and handler.__name__ in THEBE_HANDLERS:
                app.disconnect(listener.id)
    app.registry.css_files[:] = [(name, attributes) for name, attributes in app.registry.css_files
                                 if name != "sphinx-thebe.css"]
    return {"parallel_read_safe": True, "parallel_write_safe": True}
