#!/usr/bin/env python3
"""A minimal stand-in for the ``ros2`` command where the ROS 2 CLI is not installed.

The ROS 2 Jazzy wheels on PyPI do not include ros2cli. This supports the two verbs the project's
documentation uses, resolving executables exactly as ``ros2 run`` does: the package prefix from the
ament index, then ``<prefix>/lib/<package>/<executable>``.

    ros2 run <package> <executable> [args ...]   (e.g. --ros-args -p name:=value)
    ros2 pkg executables [<package>]
"""
import os
import sys

USAGE = __doc__.split("\n\n", 2)[2]


def _executables(package: str) -> list[str]:
    from ament_index_python.packages import get_package_prefix

    libdir = os.path.join(get_package_prefix(package), "lib", package)
    if not os.path.isdir(libdir):
        return []
    return sorted(
        name for name in os.listdir(libdir)
        if os.path.isfile(os.path.join(libdir, name))
        and os.access(os.path.join(libdir, name), os.X_OK)
    )


def main(argv: list[str]) -> int:
    from ament_index_python.packages import PackageNotFoundError, get_packages_with_prefixes

    if argv[:1] == ["run"] and len(argv) >= 3:
        package, executable = argv[1], argv[2]
        try:
            candidates = _executables(package)
        except PackageNotFoundError:
            print(f"Package '{package}' not found (is the workspace sourced? "
                  "source scripts/env.sh)", file=sys.stderr)
            return 1
        if executable not in candidates:
            print(f"No executable '{executable}' in package '{package}'; it has: "
                  f"{', '.join(candidates) or 'none'}", file=sys.stderr)
            return 1
        from ament_index_python.packages import get_package_prefix

        path = os.path.join(get_package_prefix(package), "lib", package, executable)
        os.execv(path, [path, *argv[3:]])
    if argv[:2] == ["pkg", "executables"]:
        packages = argv[2:] or sorted(get_packages_with_prefixes())
        for package in packages:
            try:
                for name in _executables(package):
                    print(package, name)
            except PackageNotFoundError:
                print(f"Package '{package}' not found", file=sys.stderr)
                return 1
        return 0
    print("usage: this minimal ros2 supports only:\n" + USAGE
          + "Install ROS 2 Jazzy for the full command line.", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
