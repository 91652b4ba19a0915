"""The closed loop: find what the model lacks in the residual, add it, report before and after.

This package is also the API function ``wheelcal.diagnose(...)``
(:func:`wheelcal.api.diagnose`): once the package is imported, Python binds
the name ``wheelcal.diagnose`` to it, so the package itself is callable and
forwards the call.
"""

import sys
import types


class _CallablePackage(types.ModuleType):
    def __call__(self, *args, **kwargs):
        from wheelcal.api import diagnose

        return diagnose(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
