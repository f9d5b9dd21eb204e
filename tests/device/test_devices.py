"""Device specifications (--device, PYOPENCL_CTX) resolved against the real device list.

PoCL's CPU device is always present (it is a dependency); a GPU may be present too, so every
expectation is derived from the actual list rather than assuming PoCL is device 0:0.
"""
import os
from pathlib import Path

import pyopencl as cl
import pytest

from pyopencl_rt.device import devices as dv
from pyopencl_rt.errors import DeviceSelectionError, UserError


@pytest.fixture(autouse=True)
def _no_env(monkeypatch):
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    monkeypatch.delenv("PYOPENCL_TEST", raising=False)


@pytest.fixture(scope="module")
def entries():
    found = dv.all_devices()
    assert found, "no OpenCL device at all: the pip PoCL should always be visible"
    return found


@pytest.fixture(scope="module")
def pocl(entries):
    """The (platform_index, device_index, device) entry of PoCL's CPU device."""
    matches = [e for e in entries if "portable computing language" in e[2].platform.name.lower()
               and e[2].type & cl.device_type.CPU]
    assert matches, f"PoCL CPU device not found among {[dv.describe(e).label() for e in entries]}"
    return matches[0]


def index_of(entry):
    return f"{entry[0]}:{entry[1]}"


def has_gpu(entries):
    return any(e[2].type & cl.device_type.GPU for e in entries)


def test_cpu_selects_pocl_cpu(pocl):
    chosen = dv.resolve("cpu")
    assert len(chosen) == 1
    assert chosen[0].type & cl.device_type.CPU
    assert chosen[0] == pocl[2]  # PoCL first among CPU devices
    assert dv.select_device("CPU") == pocl[2]  # case-insensitive


def test_all_returns_every_device_in_order(entries):
    assert dv.resolve("all") == [e[2] for e in entries]
    # select_device takes the first of several
    assert dv.select_device("all") == entries[0][2]


def test_index_spec(entries, pocl):
    assert dv.resolve("0:0") == [entries[0][2]]
    assert dv.resolve(index_of(pocl)) == [pocl[2]]
    # a platform index alone: the first device of that platform
    first_of_platform = [e for e in entries if e[0] == pocl[0]][0]
    assert dv.resolve(str(pocl[0])) == [first_of_platform[2]]


def test_name_substrings_select_pocl(entries, pocl):
    platform_word = pocl[2].platform.name.split()[0].lower()  # "portable"
    assert dv.resolve(platform_word) == [pocl[2]]
    assert dv.resolve(platform_word.upper()) == [pocl[2]]
    # P:D with a platform substring and an empty device part: every device of that platform
    assert dv.resolve(platform_word + ":") == [e[2] for e in entries if e[0] == pocl[0]]
    # P:D with both parts as substrings
    device_word = pocl[2].name.split()[0].split("-")[0].lower()  # "pthread" or "cpu"
    assert dv.resolve(f"{platform_word}:{device_word}")[0] == pocl[2]
    # a substring of the device name alone
    assert pocl[2] in dv.resolve(pocl[2].name.strip()[:12])


def test_comma_list_and_list_deduplicate(entries, pocl):
    idx = index_of(pocl)
    assert dv.resolve(f"cpu,{idx}") == [pocl[2]]
    assert dv.resolve(["cpu", idx, "cpu"]) == [pocl[2]]
    assert dv.resolve(["cpu, " + idx]) == [pocl[2]]
    both = dv.resolve(f"{idx},all")
    assert both[0] == pocl[2]  # order of first mention is kept
    assert len(both) == len(entries)
    assert len({d.int_ptr for d in both}) == len(both)


def test_device_object_passes_through(pocl):
    assert dv.resolve(pocl[2]) == [pocl[2]]
    assert dv.select_device(pocl[2]) == pocl[2]


def test_pyopencl_ctx_is_honoured_without_a_spec(monkeypatch, entries, pocl):
    monkeypatch.setenv("PYOPENCL_CTX", index_of(pocl))
    assert dv.select_device() == pocl[2]
    assert dv.resolve([]) == [pocl[2]]
    monkeypatch.setenv("PYOPENCL_CTX", "nosuchdevice-xyz")
    with pytest.raises(DeviceSelectionError, match="nosuchdevice-xyz"):
        dv.select_device()
    # an explicit spec wins over the environment
    assert dv.select_device("cpu") == pocl[2]


def test_default_without_spec_or_env(entries, pocl):
    chosen = dv.select_device()
    if has_gpu(entries):
        assert chosen.type & cl.device_type.GPU
    else:
        assert chosen == pocl[2]


def test_spec_matching_nothing_lists_available_devices(entries):
    with pytest.raises(DeviceSelectionError) as info:
        dv.resolve("nosuchdevice")
    msg = str(info.value)
    assert "\n" not in msg
    assert "nosuchdevice" in msg
    for e in entries:
        d = dv.describe(e)
        assert d.name in msg and d.index in msg
    assert isinstance(info.value, UserError)
    assert info.value.exit_code == 2


@pytest.mark.parametrize("spec", ["99:0", "0:99", "0:nosuchdevice", "nosuchplatform:", "cpu,nosuchdevice"])
def test_bad_index_or_partial_match_raises(spec):
    with pytest.raises(DeviceSelectionError):
        dv.resolve(spec)


def test_gpu(entries):
    if has_gpu(entries):
        chosen = dv.resolve("gpu")
        assert len(chosen) == 1 and chosen[0].type & cl.device_type.GPU
    else:
        with pytest.raises(DeviceSelectionError) as info:
            dv.resolve("gpu")
        msg = str(info.value)
        assert "\n" not in msg and "'gpu'" in msg
        assert all(dv.describe(e).name in msg for e in entries)


def test_list_devices_describes_every_device(entries, pocl):
    infos = dv.list_devices()
    assert [i.index for i in infos] == [index_of(e) for e in entries]
    info = infos[entries.index(pocl)]
    assert info.type == "CPU"
    assert info.compute_units == pocl[2].max_compute_units > 0
    assert info.global_mem_bytes == pocl[2].global_mem_size > 0
    assert info.opencl_version.startswith("OpenCL ")
    assert set(info.as_dict()) >= {"index", "platform", "name", "type", "compute_units",
                                   "global_mem_bytes", "opencl_version"}
    assert dv.device_label(pocl[2]) == info.label()


def test_pyopencl_test_env_selects_test_devices(monkeypatch, entries):
    assert dv.device_test_specs() == [index_of(e) for e in entries]
    # specs are expanded to device indices, duplicates removed ("cpu" and "0:0" may be one device)
    monkeypatch.setenv("PYOPENCL_TEST", "cpu, 0:0")
    expect = []
    for spec in ("cpu", "0:0"):
        for dev in dv.resolve(spec):
            idx = next(index_of(e) for e in entries if e[2] == dev)
            if idx not in expect:
                expect.append(idx)
    assert sorted(dv.device_test_specs()) == sorted(expect)
    # "all" means every device (it used to give only the first one)
    monkeypatch.setenv("PYOPENCL_TEST", "all")
    assert dv.device_test_specs() == [index_of(e) for e in entries]


# ----------------------------------------------------------------------------- implementations
def test_implementation_names_select_their_devices(entries):
    """``pocl`` and ``intel`` select the first device of that implementation (PoCL's platform
    "Portable Computing Language"; Intel's CPU runtime), whatever the platform order; an
    implementation that is not installed is one error line naming what is available."""
    for name in dv.IMPLEMENTATION_NAMES:
        own = [e for e in entries if dv.implementation(e[2]) == name]
        if own:
            assert dv.resolve(name) == [own[0][2]]
            assert dv.describe(own[0]).implementation == name
        else:
            with pytest.raises(DeviceSelectionError, match=f"no OpenCL device matches '{name}'; available: "):
                dv.resolve(name)
    pocl = [e for e in entries if "portable computing language" in e[2].platform.name.lower()]
    assert pocl and all(dv.implementation(e[2]) == "pocl" for e in pocl)
    assert dv.resolve("cpu")[0] == pocl[0][2] and dv.resolve(None)[0] in [e[2] for e in entries]


def fake_runtime(tmp_path):
    """A folder standing for an environment's lib/ with Intel's library in it (its contents are
    never loaded here), and a system ICD folder holding a GPU driver's ICD file."""
    lib = tmp_path / "prefix" / "lib"
    lib.mkdir(parents=True)
    (lib / "libintelocl.so").write_bytes(b"\x7fELF")
    vendors = tmp_path / "vendors"
    vendors.mkdir()
    (vendors / "nvidia.icd").write_text("libnvidia-opencl.so.1\n")
    return lib, vendors


def test_a_pip_installed_runtime_is_registered_beside_the_system_icds(tmp_path, monkeypatch):
    """The folder $OCL_ICD_VENDORS is pointed at holds every ICD file of the folder the loader
    would have read (a GPU driver stays visible) and one naming the installed library by its
    absolute path; the same files give the same folder (a second process reuses it)."""
    from pyopencl_rt.device import icd

    lib, vendors = fake_runtime(tmp_path)
    monkeypatch.setattr(icd, "_library_dirs", lambda: [tmp_path / "nowhere", lib])
    env = {icd.ENV: str(vendors), "PYOPENCL_RT_CACHE": str(tmp_path / "cache")}
    folder = icd.register(env)
    assert folder and env[icd.ENV] == folder and folder.startswith(str(tmp_path / "cache"))
    files = {p.name: p.read_text() for p in Path(folder).iterdir()}
    assert files == {"nvidia.icd": "libnvidia-opencl.so.1\n",
                     "pyopencl-rt-intel-cpu.icd": f"{(lib / 'libintelocl.so').resolve()}\n"}
    again = {icd.ENV: str(vendors), "PYOPENCL_RT_CACHE": str(tmp_path / "cache")}
    assert icd.register(again) == folder


def test_a_registered_runtime_or_the_switch_leaves_the_environment_alone(tmp_path, monkeypatch):
    """A system that already names Intel's library (an ICD installed by root), no packaged
    library, or $PYOPENCL_RT_PACKAGED_ICDS=0: nothing is written and the variable is unchanged."""
    from pyopencl_rt.device import icd

    lib, vendors = fake_runtime(tmp_path)
    monkeypatch.setattr(icd, "_library_dirs", lambda: [lib])
    cache = str(tmp_path / "cache")
    off = {icd.ENV: str(vendors), "PYOPENCL_RT_CACHE": cache, icd.SWITCH_ENV: "0"}
    assert icd.register(off) is None and off[icd.ENV] == str(vendors)
    monkeypatch.setattr(icd, "_library_dirs", lambda: [tmp_path / "nowhere"])
    bare = {icd.ENV: str(vendors), "PYOPENCL_RT_CACHE": cache}
    assert icd.register(bare) is None and bare[icd.ENV] == str(vendors)
    monkeypatch.setattr(icd, "_library_dirs", lambda: [lib])
    (vendors / "intel.icd").write_text("/opt/intel/oclcpu/x64/libintelocl.so\n")
    registered = {icd.ENV: str(vendors), "PYOPENCL_RT_CACHE": cache}
    assert icd.register(registered) is None and registered[icd.ENV] == str(vendors)
    assert not (tmp_path / "cache").exists()


def test_intel_extra_is_visible_to_a_fresh_process():
    """Where the intel extra is installed in this environment, a fresh `pyopencl-rt devices`
    lists Intel's CPU runtime with no ICD step by hand (the dev extra installs it)."""
    import json
    import os
    import subprocess
    import sys

    from pyopencl_rt.device import icd

    if not icd.packaged_libraries():
        pytest.skip("Intel's CPU runtime (pip's intel extra) is not installed in this environment")
    env = {k: v for k, v in os.environ.items() if k not in (icd.ENV, "PYOPENCL_CTX")}
    out = subprocess.run([sys.executable, "-m", "pyopencl_rt.cli", "devices", "--json"], env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    listed = json.loads(out.stdout)
    assert {"pocl", "intel"} <= {d["implementation"] for d in listed}


_PLATFORMS_AFTER = """
import sys
from pyopencl_rt.device import devices
devices.resolve(sys.argv[1] or None)
import pyopencl as cl
print("|".join(p.name for p in cl.get_platforms()))
"""


@pytest.mark.parametrize("spec, opens_packaged", [("", False), ("pocl", False),
                                                  ("cpu", True), ("intel", True), ("all", True)])
def test_a_choice_that_cannot_pick_a_packaged_runtime_leaves_it_unopened(spec, opens_packaged):
    """A fresh process whose first device choice cannot pick the pip-installed Intel runtime (the
    default, gpu, pocl) never opens it (its libraries cost about 100 MB and 0.3 s); one that can
    (cpu, intel, all) does."""
    import subprocess
    import sys

    from pyopencl_rt.device import icd

    if not icd.packaged_libraries() or icd.SWITCH_ENV in os.environ:
        pytest.skip("no pip-installed OpenCL runtime here")
    env = {k: v for k, v in os.environ.items() if k not in ("PYOPENCL_CTX", icd.ENV)}
    out = subprocess.run([sys.executable, "-c", _PLATFORMS_AFTER, spec], capture_output=True, text=True, env=env,
                         check=True).stdout.strip().split("|")
    assert ("Intel(R) OpenCL" in out) == opens_packaged and "Portable Computing Language" in out
