#!/usr/bin/env python3
"""Build the Blender extension zip: dist/hairrecon-<version>-<platform>.zip.

    .venv/bin/python scripts/build_extension.py [--wheel WHEEL] [--out-dir dist]

1. Builds the Rust module as an abi3 wheel: ``maturin build --release -m rust/python/Cargo.toml``
   (the venv's maturin), unless ``--wheel`` names one already built.
2. Stages ``addon/hairrecon`` with the wheel in ``wheels/`` and a manifest whose ``version``,
   ``wheels`` and ``platforms`` match the wheel.
3. Runs the build step of ``blender --command extension build`` (Blender's
   ``scripts/addons_core/bl_pkg/cli/blender_ext.py``, shipped inside the bpy module, run with plain
   Python) to write the zip, which installs with ``blender --command extension install-file`` and
   Preferences > Get Extensions > Install from Disk.

Prints the zip's path on the last line of stdout.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ADDON = ROOT / "addon" / "hairrecon"


def venv_bin(name: str) -> Path:
    for cand in (ROOT / ".venv" / "bin" / name, Path(sys.executable).parent / name):
        if cand.exists():
            return cand
    found = shutil.which(name)
    if found:
        return Path(found)
    raise SystemExit(f"error: {name} not found; install it in .venv (pip install {name})")


def find_blender_ext() -> Path:
    try:
        import importlib.util

        spec = importlib.util.find_spec("bpy")
        roots = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    except Exception:  # noqa: BLE001
        roots = []
    roots.append(ROOT / ".venv" / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages" / "bpy")
    for r in roots:
        hits = sorted(r.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if hits:
            return hits[-1]
    raise SystemExit("error: Blender's blender_ext.py not found; install the bpy module in .venv (pip install bpy)")


def workspace_version() -> str:
    text = (ROOT / "Cargo.toml").read_text()
    m = re.search(r"\[workspace\.package\][^\[]*?version\s*=\s*\"([^\"]+)\"", text, re.S)
    if not m:
        raise SystemExit("error: no [workspace.package] version in Cargo.toml")
    return m.group(1)


def build_wheel(out: Path) -> Path:
    cmd = [str(venv_bin("maturin")), "build", "--release", "--strip", "-m", str(ROOT / "rust/python/Cargo.toml"), "-o", str(out)]
    print("+", " ".join(cmd), flush=True)
    if subprocess.run(cmd, cwd=ROOT).returncode != 0:
        raise SystemExit("error: maturin could not build the hairrecon wheel (messages above)")
    wheels = sorted(out.glob("hairrecon-*.whl"))
    if not wheels:
        raise SystemExit(f"error: maturin wrote no hairrecon wheel into {out}")
    return wheels[-1]


def blender_platform(wheel: Path) -> str:
    """linux-x64 etc. from the wheel's platform tag (Blender's mapping, simplified)."""
    plat = wheel.stem.split("-")[-1]
    if plat.startswith(("manylinux", "musllinux", "linux")):
        system = "linux"
    elif plat.startswith("macosx"):
        system = "macos"
    elif plat.startswith("win"):
        system = "windows"
    else:
        raise SystemExit(f"error: unknown wheel platform {plat!r}")
    machine = plat.rsplit("_", 1)[-1] if not plat.endswith("x86_64") else "x86_64"
    if plat == "win_amd64":
        machine = "x64"
    machine = {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64", "arm64": "arm64"}.get(machine, machine)
    if plat.endswith("universal2"):
        raise SystemExit("error: universal2 wheels are not handled; build one per architecture")
    return f"{system}-{machine}"


def stage(wheel: Path, version: str, platform: str, dest: Path) -> None:
    shutil.copytree(ADDON, dest, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "wheels", "*.zip"))
    (dest / "wheels").mkdir()
    shutil.copy2(wheel, dest / "wheels" / wheel.name)
    manifest = (dest / "blender_manifest.toml").read_text()
    manifest, n1 = re.subn(r'(?m)^version\s*=\s*".*"$', f'version = "{version}"', manifest)
    manifest, n2 = re.subn(r"(?m)^wheels\s*=\s*\[.*\]$", f'wheels = ["./wheels/{wheel.name}"]', manifest)
    manifest, n3 = re.subn(r"(?m)^platforms\s*=\s*\[.*\]$", f'platforms = ["{platform}"]', manifest)
    if (n1, n2, n3) != (1, 1, 1):
        raise SystemExit("error: blender_manifest.toml needs one `version`, `wheels` and `platforms` line each")
    (dest / "blender_manifest.toml").write_text(manifest)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--wheel", type=Path, help="use this hairrecon wheel instead of building one")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "dist", help="where the zip goes (default: dist/)")
    args = ap.parse_args(argv)

    version = workspace_version()
    with tempfile.TemporaryDirectory(prefix="hairrecon-ext-") as tmp:
        tmp = Path(tmp)
        wheel = args.wheel.resolve() if args.wheel else build_wheel(tmp / "wheelhouse")
        if not wheel.is_file():
            raise SystemExit(f"error: {wheel} does not exist")
        if "abi3" not in wheel.name:
            raise SystemExit(f"error: {wheel.name} is not an abi3 wheel; Blender 4.2+ needs one (pyo3 abi3-py311)")
        platform = blender_platform(wheel)
        src = tmp / "hairrecon"
        stage(wheel, version, platform, src)
        args.out_dir.mkdir(parents=True, exist_ok=True)
        zip_path = (args.out_dir / f"hairrecon-{version}-{platform.replace('-', '_')}.zip").resolve()
        cmd = [sys.executable, str(find_blender_ext()), "build", "--source-dir", str(src), "--output-filepath", str(zip_path)]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd).returncode != 0:
            raise SystemExit("error: Blender's extension build failed (messages above)")
    if not zip_path.is_file():
        raise SystemExit(f"error: the extension build wrote no {zip_path}")
    print(zip_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
