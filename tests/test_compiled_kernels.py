"""The install's compiled kernels are built wherever a C compiler is.

pyproject.toml declares them optional, so that a machine without a compiler still installs and runs the
numpy code instead; where a compiler is, a failed build must not fall back to numpy unnoticed. The
tests of each kernel hold it to its numpy twin: tests/physics/test_hdr_fast.py (the HDR merge),
tests/simulators/test_sensor_kernel.py (the simulated sensor), tests/simulators/test_texture_kernel.py
(the sample's value noise), tests/simulators/test_view_kernel.py (the rays on the lit sample).
"""

import shutil
import sysconfig

import pytest

from rig.physics import hdr
from rig.simulators import camera, sensor, texture

KERNELS = {"rig.physics._merge_kernel": lambda: hdr._merge_kernel,
           "rig.simulators._sensor_kernel": lambda: sensor._sensor_kernel,
           "rig.simulators._noise_kernel": lambda: texture._noise_kernel,
           "rig.simulators._view_kernel": lambda: camera._view_kernel}


@pytest.mark.parametrize("name", sorted(KERNELS))
def test_the_kernel_is_built_where_a_c_compiler_is(name):
    compiler = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if not shutil.which(compiler):
        pytest.skip(f"no C compiler ({compiler}) here: the numpy code is the one installed")
    assert KERNELS[name]() is not None, f"{compiler} is here, but {name} was not built"
