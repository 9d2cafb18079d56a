import os
from collections.abc import Iterator

import pytest
from hypothesis import settings

# CI machines are slow and shared: deadlines make property tests flaky, not stricter.
settings.register_profile("default", deadline=None, max_examples=100)
settings.register_profile("ci", deadline=None, max_examples=60, derandomize=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")


@pytest.fixture(scope="module", params=["compiled", "python"])
def delivery_path(request: pytest.FixtureRequest) -> Iterator[str]:
    """Run a module's tests on both paths of the kernel: compiled (the channel's delivery,
    channel/_delivery.c, on the compiled event queue, aquasim_py/_events.c) and pure Python
    (the channel's reference, ``AcousticChannel.compiled_delivery = False``, on SimPy's own
    Environment: what an install without a C compiler runs). Module-scoped, so hypothesis
    tests may use it."""
    from aquasim_py import events
    from aquasim_py.channel import acoustic

    compiled = request.param == "compiled"
    if compiled and (acoustic._delivery is None or events._events is None):
        pytest.skip("the compiled extensions are not built")
    old = acoustic.AcousticChannel.compiled_delivery, events.compiled
    acoustic.AcousticChannel.compiled_delivery = events.compiled = compiled
    yield request.param
    acoustic.AcousticChannel.compiled_delivery, events.compiled = old
