"""fleetctl: mission controller for a marsupial drone team (carrier + UAV rovers) over MAVLink."""

__version__ = "0.1.0"  # keep in step with pyproject.toml; the installed package's metadata wins


def package_version() -> str:
    """The installed distribution's version (importlib.metadata), else :data:`__version__`."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fleetctl")
    except PackageNotFoundError:
        return __version__
