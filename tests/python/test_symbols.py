"""The shared library exports every function of the FMI 2.0 common and Co-Simulation APIs."""
import ctypes
import os
import zipfile
from pathlib import Path

FMI2_FUNCTIONS = """
fmi2GetTypesPlatform fmi2GetVersion fmi2SetDebugLogging fmi2Instantiate fmi2FreeInstance
fmi2SetupExperiment fmi2EnterInitializationMode fmi2ExitInitializationMode fmi2Terminate
fmi2Reset fmi2GetReal fmi2GetInteger fmi2GetBoolean fmi2GetString fmi2SetReal
fmi2SetInteger fmi2SetBoolean fmi2SetString fmi2GetFMUstate fmi2SetFMUstate
fmi2FreeFMUstate fmi2SerializedFMUstateSize fmi2SerializeFMUstate fmi2DeSerializeFMUstate
fmi2GetDirectionalDerivative fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives
fmi2DoStep fmi2CancelStep fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus
fmi2GetBooleanStatus fmi2GetStringStatus
""".split()

NAMES = ["servovalve", "manifold", "actuator", "bench", "controller"]


def fmu_dir() -> Path:
    root = Path(__file__).resolve().parents[2]
    return Path(os.environ.get("HB_FMU_DIR", root / "target" / "fmu"))


def test_every_fmi2_cosimulation_function_is_exported(tmp_path):
    assert len(FMI2_FUNCTIONS) == 34
    for name in NAMES:
        fmu = fmu_dir() / f"{name}.fmu"
        assert fmu.is_file(), f"{fmu} missing: run `bash tools/test.sh` (it packages the FMUs)"
        with zipfile.ZipFile(fmu) as z:
            binary = f"binaries/linux64/{name}.so"
            assert binary in z.namelist(), z.namelist()
            z.extract(binary, tmp_path / name)
        lib = ctypes.CDLL(str(tmp_path / name / binary))
        missing = [f for f in FMI2_FUNCTIONS if not hasattr(lib, f)]
        assert missing == [], f"{name}: missing {missing}"
        lib.fmi2GetVersion.restype = ctypes.c_char_p
        lib.fmi2GetTypesPlatform.restype = ctypes.c_char_p
        assert lib.fmi2GetVersion() == b"2.0"
        assert lib.fmi2GetTypesPlatform() == b"default"
