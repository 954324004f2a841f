"""The README's Python quick-start block and its shell commands run as written."""
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

# Commands the suite does not run here, each with why (they run in `make demo` / benchmarks; the
# real pendulum's two commands, 25 s, in tests/test_real_pendulum.py, slow).
LONG = ("make ", "lsindy reproduce", "lsindy swingup", "python benchmarks/", "python mpc/",
        "lsindy identify examples/data/real_pendulum/", "python examples/real_pendulum.py")


def test_readme_python_block_runs(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README has no python block"
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], "README.md", "exec"), {})


def shell_commands():
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", README.read_text(), flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("  #")[0].strip()
            if line:
                commands.append(line)
    return commands


def test_readme_shell_commands_run_as_typed(tmp_path):
    """From a folder laid out like the repository (examples/ present), with the venv active."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    env = dict(os.environ, PATH=str(Path(sys.executable).parent) + os.pathsep + os.environ["PATH"])
    ran = 0
    for cmd in shell_commands():
        if cmd.startswith(LONG) or cmd == ". .venv/bin/activate":
            continue
        done = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, f"{cmd}\n{done.stderr}"
        ran += 1
    assert ran >= 6
