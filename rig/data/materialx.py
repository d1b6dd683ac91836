"""A fitted microfacet model as a MaterialX document (`rig export --format materialx`; docs/materialx.md).

MaterialX 1.39's standard library has the pieces of rig's `mrm`, `mrm_diffuse` and `ggx` models
(rig.physics.brdf_models), so the document uses only standard nodes:

- the microfacet lobe is `generalized_schlick_bsdf` with color0 = F0, color82 = color90 = 1 and exponent 5 (the
  plain Schlick Fresnel F0 + (1 − F0)(1 − u)⁵ of our models: a white F82 tint adds no correction), roughness =
  (α, α) with α = roughness² (MaterialX's `roughness` is GGX's α; ours is the perceptual roughness, as OpenPBR's),
  GGX with height-correlated Smith, as ours; `retroreflective = true` for MRM: the node then reflects the view
  about the normal before evaluating, which is MRM's definition f_MRM(o, i) = f_GGX(o', i);
- the Lambertian base of `mrm_diffuse` is `oren_nayar_diffuse_bsdf` with color = kd and roughness 0 (Lambert);
- `add` sums the two lobes; `surface` and `surfacematerial` make it a material.

OpenPBR, the surface that MRM was made for, gains `specular_retroreflectivity` in its 1.2 development branch; a
pure MRM fit maps onto it exactly (base_metalness 1, base_color = F0, specular_color 1, specular_roughness =
roughness, specular_retroreflectivity 1). The export uses `open_pbr_surface` for an MRM fit when the installed
MaterialX declares that input, and otherwise the graph above, saying why. MRM + diffuse never maps onto OpenPBR
(base_color would be both the metal's F0 and the diffuse albedo).

The document is written with the standard library's XML (no MaterialX needed to write it); the MaterialX package,
when installed, is only asked whether its OpenPBR has the input.
"""

from __future__ import annotations

import importlib
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig import __version__
from rig.data.output_folder import new_file

#: The MaterialX version the documents declare (the standard library that has `retroreflective`).
MTLX_VERSION = "1.39"
MODELS = ("mrm", "mrm_diffuse", "ggx")
OPENPBR_NODEDEF = "ND_open_pbr_surface_surfaceshader"
RETRO_INPUT = "specular_retroreflectivity"


class MaterialXError(ValueError):
    """The fit cannot be written as MaterialX; the message says why."""


@dataclass(frozen=True)
class MaterialXExport:
    path: Path
    note: str           # which surface was used, and why


def openpbr_retroreflectivity() -> bool | None:
    """Whether the installed MaterialX's `open_pbr_surface` declares `specular_retroreflectivity`; None when the
    MaterialX package is not installed."""
    try:
        mx = importlib.import_module("MaterialX")      # optional; untyped (no stubs), hence not a plain import
    except ImportError:
        return None
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    nodedef = lib.getNodeDef(OPENPBR_NODEDEF)
    return bool(nodedef is not None and nodedef.getActiveInput(RETRO_INPUT) is not None)


def _name(text: str) -> str:
    """A valid MaterialX element name from free text (letters, digits, underscores; not starting with a digit)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text).strip("_") or "rig"
    return f"m_{name}" if name[0].isdigit() else name


def _input(node: ET.Element, name: str, kind: str, value: str | None = None, nodename: str | None = None) -> None:
    attrs = {"name": name, "type": kind}
    attrs.update({"value": value} if value is not None else {"nodename": nodename or ""})
    ET.SubElement(node, "input", attrs)


def _color(v: float) -> str:
    return f"{v!r}, {v!r}, {v!r}"


def _node(root: ET.Element, category: str, name: str, kind: str) -> ET.Element:
    return ET.SubElement(root, category, {"name": name, "type": kind})


def _microfacet(root: ET.Element, params: Mapping[str, float], retroreflective: bool) -> str:
    alpha = params["roughness"] ** 2
    lobe = _node(root, "generalized_schlick_bsdf", "retroreflective_lobe" if retroreflective else "specular_lobe",
                 "BSDF")
    _input(lobe, "color0", "color3", _color(params["f0"]))
    _input(lobe, "color82", "color3", _color(1.0))
    _input(lobe, "color90", "color3", _color(1.0))
    _input(lobe, "exponent", "float", "5")
    _input(lobe, "roughness", "vector2", f"{alpha!r}, {alpha!r}")
    _input(lobe, "retroreflective", "boolean", "true" if retroreflective else "false")
    return lobe.attrib["name"]


def _graph(root: ET.Element, model: str, params: Mapping[str, float]) -> str:
    """The lower-level graph; returns the name of the surfaceshader node."""
    bsdf = _microfacet(root, params, retroreflective=model != "ggx")
    if model == "mrm_diffuse":
        diffuse = _node(root, "oren_nayar_diffuse_bsdf", "diffuse_lobe", "BSDF")
        _input(diffuse, "color", "color3", _color(params["kd"]))
        _input(diffuse, "roughness", "float", "0")
        add = _node(root, "add", "lobes", "BSDF")
        _input(add, "in1", "BSDF", nodename=diffuse.attrib["name"])
        _input(add, "in2", "BSDF", nodename=bsdf)
        bsdf = add.attrib["name"]
    surface = _node(root, "surface", "surface", "surfaceshader")
    _input(surface, "bsdf", "BSDF", nodename=bsdf)
    return surface.attrib["name"]


def _openpbr(root: ET.Element, params: Mapping[str, float]) -> str:
    surface = _node(root, "open_pbr_surface", "surface", "surfaceshader")
    for name, kind, value in (("base_weight", "float", "1"), ("base_color", "color3", _color(params["f0"])),
                              ("base_metalness", "float", "1"), ("specular_weight", "float", "1"),
                              ("specular_color", "color3", _color(1.0)),
                              ("specular_roughness", "float", repr(params["roughness"])),
                              (RETRO_INPUT, "float", "1")):
        _input(surface, name, kind, value)
    return surface.attrib["name"]


def materialx_document(fit: Mapping[str, Any], name: str, source: str,
                       openpbr_retro: bool | None) -> tuple[str, str]:
    """(the .mtlx text, the note saying which surface it uses and why) for a `rig fit --json` result."""
    model, params = fit["model"], fit["params"]
    if model not in MODELS:
        raise MaterialXError(f"{source}: a {model} fit has no MaterialX form; --format materialx takes a fit of "
                             f"{', '.join(MODELS)} (the microfacet models that MaterialX's standard nodes express)")
    if model == "mrm" and openpbr_retro:
        note = f"OpenPBR: the installed MaterialX's open_pbr_surface has {RETRO_INPUT}, which expresses MRM exactly"
    else:
        why = {None: "the MaterialX package is not installed, so whether its open_pbr_surface has "
                     f"{RETRO_INPUT} (OpenPBR 1.2) could not be checked",
               False: f"the installed MaterialX's open_pbr_surface has no {RETRO_INPUT} (OpenPBR 1.2; 1.1.1 ships)",
               True: "an MRM + diffuse fit does not map onto OpenPBR (base_color would be both F0 and the albedo)"
                     if model == "mrm_diffuse" else "a GGX fit is a plain microfacet lobe"}[openpbr_retro]
        nodes = "generalized_schlick_bsdf" + ", oren_nayar_diffuse_bsdf, add" * (model == "mrm_diffuse")
        note = f"standard-library graph ({nodes}), not open_pbr_surface: {why}"
    root = ET.Element("materialx", {"version": MTLX_VERSION})
    values = ", ".join(f"{k} = {v!r}" for k, v in params.items())
    comment = f" rig {__version__}: {model} fit ({values}) from {source}; {note} "
    root.append(ET.Comment(comment.replace("--", "- -")))            # "--" may not appear in an XML comment
    surface = _openpbr(root, params) if model == "mrm" and openpbr_retro else _graph(root, model, params)
    material = _node(root, "surfacematerial", _name(name), "material")
    material.set("doc", f"{model} fit by rig: {values}; GGX alpha = roughness^2")
    _input(material, "surfaceshader", "surfaceshader", nodename=surface)
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n", note


def export_materialx(fit: Mapping[str, Any], out: Path, name: str, source: str) -> MaterialXExport:
    """Write the .mtlx under a temporary name, named when complete (never over an existing file)."""
    text, note = materialx_document(fit, name, source, openpbr_retroreflectivity())
    with new_file(Path(out)) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return MaterialXExport(Path(out), note)
