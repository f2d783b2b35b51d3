"""Put this folder first on PYTHONPATH and, in every Python process started with it (a demo, evaluate.py, a
training node under roslaunch), any call into hopper_training.controller raises: once a module of that package
has been imported, every function it defines and every method of every class it defines is replaced by one that
raises ControllerRefused. Its import still works (its module-level code has run), so a program that only imports
it starts; a program that calls it fails with a traceback naming the call. Set REFUSED_CONTROLLER_LOG to a file
and each process that imported a controller module appends one line naming it (the proof that the hook ran).

Python imports sitecustomize at start-up (the site module), the first one on sys.path: this one shadows Debian's
(/etc/python3.11/sitecustomize.py, apport's exception hook, which it then runs as well).
"""
from __future__ import annotations

import functools
import importlib.abc
import importlib.machinery
import os
import sys
import types

PACKAGE = "hopper_training.controller"


class ControllerRefused(AssertionError):
    """A call into hopper_training.controller, in a process where it is refused."""


def _refusing(name: str):
    def refused(*args, **kwargs):
        raise ControllerRefused(f"{name} was called, but the controller is refused in this process "
                                f"(test/programs/refuse_controller)")
    return refused


def _wrapped(value, name):
    if isinstance(value, types.FunctionType):
        return functools.wraps(value)(_refusing(name))
    if isinstance(value, staticmethod):
        return staticmethod(_refusing(name))
    if isinstance(value, classmethod):
        return classmethod(_refusing(name))
    if isinstance(value, property):
        return property(_refusing(name))
    return None


def refuse(module: types.ModuleType) -> int:
    """Replace every function and method that `module` defines by a raising one; returns how many."""
    count = 0
    for attr, value in list(vars(module).items()):
        if getattr(value, "__module__", None) != module.__name__:
            continue
        if isinstance(value, type):
            for method_name, method in list(vars(value).items()):
                replacement = _wrapped(method, f"{module.__name__}.{value.__qualname__}.{method_name}")
                if replacement is not None:
                    setattr(value, method_name, replacement)
                    count += 1
        else:
            replacement = _wrapped(value, f"{module.__name__}.{attr}")
            if replacement is not None:
                setattr(module, attr, replacement)
                count += 1
    return count


class _RefusingLoader(importlib.abc.Loader):
    def __init__(self, loader):
        self.loader = loader

    def create_module(self, spec):
        return self.loader.create_module(spec)

    def exec_module(self, module):
        self.loader.exec_module(module)
        count = refuse(module)
        log = os.environ.get("REFUSED_CONTROLLER_LOG")
        if log:
            with open(log, "a", encoding="utf-8") as out:
                out.write(f"{os.getpid()} {module.__name__} {count}\n")


class _RefusingFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path, target=None):
        if fullname != PACKAGE and not fullname.startswith(PACKAGE + "."):
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _RefusingLoader(spec.loader)
        return spec


sys.meta_path.insert(0, _RefusingFinder())

try:  # Debian's own sitecustomize, which this one shadows
    import apport_python_hook
except ImportError:
    pass
else:
    apport_python_hook.install()
