"""VTK's compiled modules loaded so that no library loaded before them can replace their C++
template code (the cause, and the one import rule it leaves, are in contactvisco.post.render).

    install()        # done by `import contactvisco`; idempotent
    loaded_here()    # True when VTK's core module was loaded through install()'s finder

Only os, sys and importlib are imported here: `import contactvisco` stays light.
"""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import sys

#: dlopen flags for VTK's extension modules: their own symbols first (RTLD_DEEPBIND, glibc),
#: not exported to later libraries (RTLD_LOCAL).
FLAGS = os.RTLD_NOW | os.RTLD_LOCAL | getattr(os, "RTLD_DEEPBIND", 0)

_state = {"core": False}


class _Loader(importlib.abc.Loader):
    """An extension module loader that opens the shared object with FLAGS."""

    def __init__(self, inner):
        self.inner = inner

    def create_module(self, spec):
        before = sys.getdlopenflags()
        sys.setdlopenflags(FLAGS)
        try:
            module = self.inner.create_module(spec)
        finally:
            sys.setdlopenflags(before)
        if spec.name == "vtkmodules.vtkCommonCore":
            _state["core"] = True
        return module

    def exec_module(self, module):
        self.inner.exec_module(module)


class _PackageLoader(importlib.abc.Loader):
    """The loader of the vtkmodules package, which puts its own finder first on
    sys.meta_path: ours goes back in front of it."""

    def __init__(self, inner):
        self.inner = inner

    def create_module(self, spec):
        return self.inner.create_module(spec)

    def exec_module(self, module):
        self.inner.exec_module(module)
        _to_front()


class _Finder(importlib.abc.MetaPathFinder):
    """Finds vtkmodules.vtk* extension modules with the other finders and loads them with
    _Loader; everything else is left to the other finders."""

    def find_spec(self, name, path, target=None):
        if name != "vtkmodules" and not name.startswith("vtkmodules.vtk"):
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is None:
                continue
            if name == "vtkmodules":
                spec.loader = _PackageLoader(spec.loader)
            elif isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
                spec.loader = _Loader(spec.loader)
            return spec
        return None


def _to_front() -> None:
    mine = [finder for finder in sys.meta_path if isinstance(finder, _Finder)]
    for finder in mine:
        sys.meta_path.remove(finder)
    sys.meta_path.insert(0, mine[0] if mine else _Finder())


#: Where the EGL library of a Linux system is looked for.
EGL_LIBRARIES = ("/usr/lib/x86_64-linux-gnu/libEGL.so.1", "/usr/lib/aarch64-linux-gnu/libEGL.so.1",
                 "/usr/lib64/libEGL.so.1", "/usr/lib/libEGL.so.1")


def headless_rendering() -> None:
    """Without a display, VTK's render windows are EGL's where the system has EGL: VTK (9.4
    on) otherwise tries X first and warns "bad X server connection" before it falls back.
    A choice made in the environment (VTK_DEFAULT_OPENGL_WINDOW) is kept."""
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    if any(os.path.exists(path) for path in EGL_LIBRARIES):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def install() -> None:
    """Put the finder first on sys.meta_path (once; a no-op where dlopen has no
    RTLD_DEEPBIND, i.e. outside glibc), and choose headless rendering without a display."""
    headless_rendering()
    if not hasattr(os, "RTLD_DEEPBIND"):
        return
    if not any(isinstance(finder, _Finder) for finder in sys.meta_path):
        _to_front()


def loaded_here() -> bool:
    """True when vtkmodules.vtkCommonCore was loaded with FLAGS (through the finder)."""
    return _state["core"]
