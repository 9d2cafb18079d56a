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
    """Run a module's tests on both delivery paths of the channel: the compiled one
    (channel/_delivery.c) and the Python reference (``AcousticChannel.compiled_delivery``).
    Module-scoped, so hypothesis tests may use it."""
    from aquasim_py.channel import acoustic

    if request.param == "compiled" and acoustic._delivery is None:
        pytest.skip("aquasim_py.channel._delivery is not built")
    old = acoustic.AcousticChannel.compiled_delivery
    acoustic.AcousticChannel.compiled_delivery = request.param == "compiled"
    yield request.param
    acoustic.AcousticChannel.compiled_delivery = old
