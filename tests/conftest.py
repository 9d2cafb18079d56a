import os

from hypothesis import settings

# CI machines are slow and shared: deadlines make property tests flaky, not stricter.
settings.register_profile("default", deadline=None, max_examples=100)
settings.register_profile("ci", deadline=None, max_examples=60, derandomize=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")
