"""`rig export --format materialx`: an MRM fit of the CEA yellow tape (tests/data/cea-retro) as a MaterialX
document that MaterialX itself validates and compiles to GLSL, its parameters read back through MaterialX's
API; MRM + diffuse and GGX documents likewise; other models refused with one message."""

import json

import pytest

from rig.cli.main import main
from rig.data.materialx import materialx_document

mx = pytest.importorskip("MaterialX")


def _document(text: str):
    doc = mx.createDocument()
    mx.readFromXmlString(doc, text)
    return doc


def _validated(doc):
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc.importLibrary(lib)
    valid, message = doc.validate()
    assert valid, message
    return doc


def _glsl(doc) -> str:
    gen_shader = pytest.importorskip("MaterialX.PyMaterialXGenShader")
    gen_glsl = pytest.importorskip("MaterialX.PyMaterialXGenGlsl")
    generator = gen_glsl.GlslShaderGenerator.create()
    context = gen_shader.GenContext(generator)
    context.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    shader = generator.generate("rig_material", doc.getMaterialNodes()[0], context)
    return shader.getSourceCode(gen_shader.PIXEL_STAGE)


@pytest.fixture(scope="module")
def yellow_fit(cea_dir, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mtlx")
    assert main(["import", str(cea_dir / "retro-3M-yellow.alta"), "--out", str(tmp / "yellow")]) == 0
    assert main(["fit", str(tmp / "yellow"), "--model", "mrm", "--unweighted", "--json", str(tmp / "mrm.json")]) == 0
    return tmp


def test_mrm_fit_of_the_yellow_tape(yellow_fit, capsys):
    out = yellow_fit / "tape.mtlx"
    capsys.readouterr()
    assert main(["export", str(yellow_fit / "yellow"), "--format", "materialx", "--fit", str(yellow_fit / "mrm.json"),
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "not open_pbr_surface" in err and "specular_retroreflectivity" in err      # says why the graph
    doc = _validated(_document(out.read_text()))
    fit = json.loads((yellow_fit / "mrm.json").read_text())["params"]
    (lobe,) = doc.getNodes("generalized_schlick_bsdf")
    alpha = lobe.getInputValue("roughness")                        # MaterialX holds it in single precision
    assert alpha[0] == pytest.approx(fit["roughness"] ** 2, rel=1e-6) and alpha[1] == alpha[0]
    written = [float(v) for v in lobe.getInput("roughness").getValueString().split(",")]
    assert written == [fit["roughness"] ** 2] * 2                  # the file itself: α = roughness², exactly
    assert lobe.getInputValue("retroreflective") is True
    assert lobe.getInputValue("color0")[1] == pytest.approx(fit["f0"], rel=1e-6)
    assert tuple(lobe.getInputValue("color90")) == (1.0, 1.0, 1.0) and lobe.getInputValue("exponent") == 5.0
    assert "mx_generalized_schlick_bsdf" in _glsl(doc)


@pytest.mark.parametrize("model, params, nodes", [
    ("mrm_diffuse", {"kd": 0.3, "roughness": 0.23, "f0": 0.19},
     {"generalized_schlick_bsdf", "oren_nayar_diffuse_bsdf", "add"}),
    ("ggx", {"roughness": 0.4, "f0": 0.5}, {"generalized_schlick_bsdf"}),
])
def test_mrm_diffuse_and_ggx(model, params, nodes):
    text, note = materialx_document({"model": model, "params": params}, "a sample", "fit.json", False)
    doc = _validated(_document(text))
    assert {n.getCategory() for n in doc.getNodes()} == nodes | {"surface", "surfacematerial"}
    (lobe,) = doc.getNodes("generalized_schlick_bsdf")
    assert lobe.getInputValue("retroreflective") is (model != "ggx")
    assert lobe.getInputValue("roughness")[0] == pytest.approx(params["roughness"] ** 2)
    if model == "mrm_diffuse":
        (diffuse,) = doc.getNodes("oren_nayar_diffuse_bsdf")
        assert diffuse.getInputValue("color")[0] == pytest.approx(0.3) and diffuse.getInputValue("roughness") == 0
    assert _glsl(doc)


def test_openpbr_when_it_has_retroreflectivity():
    """A MaterialX whose OpenPBR declares specular_retroreflectivity (OpenPBR 1.2) gets the exact mapping."""
    text, note = materialx_document({"model": "mrm", "params": {"roughness": 0.23, "f0": 0.19}}, "s", "f.json", True)
    doc = _document(text)
    (surface,) = doc.getNodes("open_pbr_surface")
    assert surface.getInputValue("specular_retroreflectivity") == 1.0
    assert surface.getInputValue("specular_roughness") == pytest.approx(0.23)       # OpenPBR's own roughness
    assert surface.getInputValue("base_metalness") == 1.0 and "OpenPBR" in note


def test_other_models_refused(e2e_run, tmp_path, capsys):
    fit = tmp_path / "lambert.json"
    fit.write_text(json.dumps({"model": "lambert", "params": {"kd": 0.5}}))
    out = tmp_path / "x.mtlx"
    assert main(["export", str(e2e_run), "--format", "materialx", "--fit", str(fit), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "a lambert fit has no MaterialX form" in err and "mrm, mrm_diffuse, ggx" in err and not out.exists()
