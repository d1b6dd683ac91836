"""A fitted BRDF model as a Radiance `.cal` function, the input of `bsdf2ttree -t3 -f FILE.cal rig_bsdf`.

Radiance's convention for such a function (bsdf2ttree(1), Ward, LBNL-ETA/Radiance): six arguments,
the incident then the exiting unit vector, both pointing away from the surface, +z the front
normal, +y "up"; it returns the BSDF in sr⁻¹. That is rig's SCS (docs/geometry.md) with ωi
toward the lamp and ωo toward the camera, so the vectors go in unchanged: (ix, iy, iz) = ωi,
(ox, oy, oz) = ωo. `bsdf2ttree` samples the function over both hemispheres; the functions are
zero unless both vectors are above the surface (iz > 0 and oz > 0), as `rig.physics.brdf_models`.

The expressions are those of `rig.physics.brdf_models` (each cites its paper), written in
Radiance's calc language: `name : value;` a constant, `if(c, a, b)` is a when c > 0, `PI`.
The mirror of i about the normal is (−ix, −iy, iz), so i_s·o = −ix·ox − iy·oy + iz·oz.
"""

from __future__ import annotations

from collections.abc import Mapping

from rig.physics.brdf_models import get_model

#: Name of the function every written `.cal` defines.
FUNCTION = "rig_bsdf"

_PRELUDE = """noneg(x) : if(x, x, 0);
{ normalised Phong lobe (n+2)/(2 PI) max(0, c)^n }
phong_lobe(c) : (n + 2)/(2*PI)*noneg(c)^n;
{ i.o and i_s.o, i_s the mirror of i about the normal }
i_dot_o(ix,iy,iz,ox,oy,oz) : ix*ox + iy*oy + iz*oz;
is_dot_o(ix,iy,iz,ox,oy,oz) : -ix*ox - iy*oy + iz*oz;
"""

#: f(ωi, ωo) of each model over the upper hemispheres, in terms of ix..oz and the model's parameters.
_EXPRESSIONS = {
    "lambert": "kd/PI",
    "modified_phong": "kd/PI + ks*phong_lobe(is_dot_o(ix,iy,iz,ox,oy,oz))",
    "retrophong": ("kd/PI + k3*exp(k4*(1 - iz))*phong_lobe(is_dot_o(ix,iy,iz,ox,oy,oz))"
                   " + (k1*(1 - iz) + k2)*phong_lobe(i_dot_o(ix,iy,iz,ox,oy,oz))"),
}
#: Models a `.cal` can be written for.
CAL_MODELS = tuple(_EXPRESSIONS)


def model_cal(model: str, params: Mapping[str, float]) -> str:
    """Text of a `.cal` file defining `rig_bsdf(ix,iy,iz,ox,oy,oz)` = the model with these parameters, sr⁻¹.

    `model` and `params` are what `rig fit --json` writes ("model", "params"). Raises ValueError for a
    model without a `.cal` expression or parameters that do not match the model's.
    """
    if model not in _EXPRESSIONS:
        raise ValueError(f"no Radiance .cal for model {model!r}; available: {', '.join(CAL_MODELS)}")
    names = get_model(model).param_names
    if set(params) != set(names):
        raise ValueError(f"{model} takes parameters {', '.join(names)}; got {', '.join(sorted(params)) or 'none'}")
    constants = "".join(f"{name} : {float(params[name])!r};\n" for name in names)
    return (f"{{ rig: BRDF model {model} ({get_model(model).citation}), f_r in 1/sr }}\n"
            f"{{ vectors normalised, pointing away from the surface: i toward the source, o toward the viewer }}\n"
            f"{constants}{_PRELUDE}"
            f"{FUNCTION}(ix,iy,iz,ox,oy,oz) : if(iz, if(oz, {_EXPRESSIONS[model]}, 0), 0);\n")
