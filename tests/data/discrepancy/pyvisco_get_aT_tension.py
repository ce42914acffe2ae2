"""Writes pyvisco_tension_get_aT.csv: pyvisco's own shift factors of dma_tension_raw.csv.

Not run by the tests (it needs pandas and the pyvisco 2.1.3 sdist, which the project does not
depend on). pyvisco's ``master.get_aT`` shifts each temperature step onto its neighbour by a
power-law fit of the storage modulus E' (reference -5 C, the temperature of the example's
published shift factors). Run:

    pip download --no-deps --no-binary :all: pyvisco==2.1.3 -d /tmp/pyvisco
    tar xzf /tmp/pyvisco/pyvisco-2.1.3.tar.gz -C /tmp/pyvisco
    python tests/data/discrepancy/pyvisco_get_aT_tension.py /tmp/pyvisco/pyvisco-2.1.3

(with pandas, numpy and scipy installed).
"""
import importlib.util
import sys
import types
from pathlib import Path

HERE = Path(__file__).resolve().parent


def load_module(root: Path, name: str):
    # the package's __init__ imports its notebook widgets: load the two modules alone
    spec = importlib.util.spec_from_file_location(f"pyvisco.{name}",
                                                  root / "pyvisco" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[f"pyvisco.{name}"] = module
    spec.loader.exec_module(module)
    return module


def main(root: Path) -> None:
    package = types.ModuleType("pyvisco")
    package.__path__ = [str(root / "pyvisco")]
    sys.modules["pyvisco"] = package
    load, master = load_module(root, "load"), load_module(root, "master")
    df_raw = load.user_raw((HERE / "dma_tension_raw.csv").read_bytes(), "freq", "E")[0]
    df_at, _ = master.get_aT(df_raw, -5)
    with open(HERE / "pyvisco_tension_get_aT.csv", "w", encoding="utf-8") as f:
        f.write("T,log_aT\nC, -\n")
        for t, a in zip(df_at["T"], df_at["log_aT"]):
            f.write(f"{t:g},{a:.4f}\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
