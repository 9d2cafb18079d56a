"""Node behaviours (protocols) built on aquasim_py, one package per protocol family.

Installed as ``aquasim_protocols`` (the top-level ``protocols/`` folder is mapped there by
``pyproject.toml``), so nothing named ``protocols`` lands in site-packages. Each family package
holds its node behaviour (``node.py``, SimPy), its paper's maths (``math.py``, pure numpy /
scipy), its metrics (``metrics.py``, from trace tables) and its baselines; importing the package
registers its protocols with :mod:`aquasim_py.registry`. ``common`` holds behaviour shared by
several families (the periodic beacon cycle).
"""
