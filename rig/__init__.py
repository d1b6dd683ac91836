"""rig: control and acquisition software for image-based BRDF goniophotometers.

One import name; the card's drivers/ and simulators/ install as rig.drivers and rig.simulators. The packages,
each importing only from the layers below it (import-linter, pyproject.toml; docs/architecture.md follows
one point through them):

    rig.cli                                      the `rig` command line (rig.cli.main:main)
    rig.monitor | rig.report | rig.bench         `rig monitor`, `rig report`, `rig bench`'s method studies
    rig.session                                  opening the rig a command runs on; the adaptive sampler
    rig.acquisition | rig.simulators | rig.analysis   running a campaign; the simulated rig; fits and predictors
    rig.data | rig.devices | rig.calibration     the dataset folder and formats; connecting a rig file's
                                                 devices; calibration procedures
    rig.planning                                 campaign → plan
    rig.config                                   campaign, rig and calibration files
    rig.physics | rig.drivers                    pure physics and metrology; device interfaces and drivers
    rig.core                                     values, errors, exit codes, the clock, event kinds

Each package's docstring says what it owns, its entry points and what it may import.
"""

__version__ = "0.1.0"
