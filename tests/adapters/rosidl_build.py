"""RIHS01 type hashes of messages no wheel ships (map_msgs, nav2_msgs), computed by ROS 2's own rosidl
generators from the ``.msg`` text: ``rosidl_adapter`` turns it into IDL and
``rosidl_generator_type_description`` hashes it against the type descriptions the wheels install
(``share/<package>/msg/*.json``), exactly as a ROS 2 build does. No code shared with ``adapters.ros``."""

from __future__ import annotations

import contextlib
import io
import json
import sysconfig
from pathlib import Path

from rosidl_adapter.msg import convert_msg_to_idl
from rosidl_generator_type_description import generate_type_hash


def share(package: str) -> Path:
    """Where the ROS 2 wheels install a package's share folder: ``<environment>/share/<package>``
    (found without AMENT_PREFIX_PATH, which the wheels do not need)."""
    path = Path(sysconfig.get_paths()["data"]) / "share" / package
    if not path.is_dir():
        msg = f"The ROS 2 package {package!r} is not installed here ({path}): install the dev extra."
        raise FileNotFoundError(msg)
    return path


def shipped_hash(type_name: str) -> str:
    """The RIHS01 hash a wheel ships for ``type_name`` (``pkg/msg/Name``)."""
    package, _, name = type_name.split("/")
    data = json.loads((share(package) / "msg" / f"{name}.json").read_text())
    return str(next(h["hash_string"] for h in data["type_hashes"] if h["type_name"] == type_name))


def generated_hash(type_name: str, definition: str, work: Path, depends: tuple[str, ...]) -> str:
    """The RIHS01 hash of ``type_name`` defined by ``definition`` (``.msg`` text), whose fields use
    types of the installed packages ``depends``."""
    package, _, name = type_name.split("/")
    source = work / package
    (source / "msg").mkdir(parents=True, exist_ok=True)
    (source / "msg" / f"{name}.msg").write_text(definition)
    with contextlib.redirect_stdout(io.StringIO()):  # the generators narrate
        convert_msg_to_idl(source, package, Path("msg") / f"{name}.msg", source / "msg")
    out = work / "generated"
    arguments = work / "arguments.json"
    arguments.write_text(
        json.dumps(
            {
                "package_name": package,
                "output_dir": str(out),
                "idl_tuples": [f"{source}:msg/{name}.idl"],
                "include_paths": [f"{dep}:{share(dep)}" for dep in depends],
            }
        )
    )
    generate_type_hash(str(arguments))
    data = json.loads((out / "msg" / f"{name}.json").read_text())
    return str(data["type_hashes"][0]["hash_string"])


def generated_package_hashes(
    package: str, definitions: dict[str, str], work: Path, depends: tuple[str, ...]
) -> dict[str, str]:
    """The RIHS01 hashes of every message of ``package`` (name -> ``.msg`` text), generated together as
    a ROS 2 build of that package does (its messages may use each other), against the installed
    packages ``depends``: ``{"pkg/msg/Name": "RIHS01_..."}``."""
    source = work / package
    (source / "msg").mkdir(parents=True, exist_ok=True)
    for name, definition in definitions.items():
        (source / "msg" / f"{name}.msg").write_text(definition)
        with contextlib.redirect_stdout(io.StringIO()):
            convert_msg_to_idl(source, package, Path("msg") / f"{name}.msg", source / "msg")
    out = work / "generated"
    arguments = work / "arguments.json"
    arguments.write_text(
        json.dumps(
            {
                "package_name": package,
                "output_dir": str(out),
                "idl_tuples": [f"{source}:msg/{name}.idl" for name in definitions],
                "include_paths": [f"{dep}:{share(dep)}" for dep in depends],
            }
        )
    )
    generate_type_hash(str(arguments))
    hashes: dict[str, str] = {}
    for name in definitions:
        data = json.loads((out / "msg" / f"{name}.json").read_text())
        hashes[f"{package}/msg/{name}"] = str(data["type_hashes"][0]["hash_string"])
    return hashes
