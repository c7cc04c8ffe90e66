"""scripts/slurm_bake.sh against a real Slurm on this machine: munged, slurmctld and slurmd are started
from a generated configuration (a one-node cluster, ports of their own, everything under a temporary
folder), a 4-shard bake must equal `photonlm bake` bit for bit with one shard killed once (and requeued),
so must one whose direct pass and final gather run as arrays of texel ranges (a gather task killed once),
a shard that stays dead must fail the merge cleanly, and the daemons are stopped. Skips, saying why,
where Slurm is not installed (Debian: apt-get install slurmd slurmctld slurm-client munge) or this is
not root (the daemons run as root here)."""
import json
import os
import shutil
import signal
import socket
import subprocess
import time

import pytest

from test_cli import CLI
from test_cli_shards import SCENE, outputs

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts", "slurm_bake.sh")
DAEMONS = ("munged", "slurmctld", "slurmd", "sbatch", "scontrol", "sinfo")


def why_not():
    if CLI is None or not os.access(CLI, os.X_OK):
        return "the photonlm CLI was not found (set PHOTONLM_LIBRARY)"
    missing = [d for d in DAEMONS if shutil.which(d) is None and not os.access("/usr/sbin/" + d, os.X_OK)]
    if missing:
        return ("Slurm is not installed (%s missing): apt-get install slurmd slurmctld slurm-client munge"
                % ", ".join(missing))
    if os.geteuid() != 0:
        return "the test starts munged, slurmctld and slurmd as root; this is not root"
    if not os.path.exists("/etc/munge/munge.key"):
        return "no /etc/munge/munge.key (the munge package makes one on installation)"
    return None


pytestmark = pytest.mark.skipif(why_not() is not None, reason=str(why_not()))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def daemon(name):
    return shutil.which(name) or "/usr/sbin/" + name


@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    root = tmp_path_factory.mktemp("slurm")
    munge = root / "munge"
    for d in ("munge", "state", "spool", "log"):
        (root / d).mkdir()
    os.chmod(munge, 0o700)
    shutil.copy("/etc/munge/munge.key", munge / "munge.key")
    os.chown(munge / "munge.key", 0, 0)
    os.chmod(munge / "munge.key", 0o600)
    host = socket.gethostname().split(".")[0]
    conf = root / "slurm.conf"
    # cred_expire: how long a requeued job waits before it may start again (120 s by default).
    conf.write_text("\n".join([
        "ClusterName=photonlmtest", "SlurmctldHost=%s" % host,
        "SlurmctldPort=%d" % free_port(), "SlurmdPort=%d" % free_port(),
        "AuthType=auth/munge", "CredType=cred/munge",
        "AuthInfo=socket=%s,cred_expire=5" % (munge / "sock"),
        "SlurmUser=root", "SlurmdUser=root",
        "StateSaveLocation=%s" % (root / "state"), "SlurmdSpoolDir=%s" % (root / "spool"),
        "SlurmctldPidFile=%s" % (root / "slurmctld.pid"), "SlurmdPidFile=%s" % (root / "slurmd.pid"),
        "SlurmctldLogFile=%s" % (root / "log" / "slurmctld.log"), "SlurmdLogFile=%s" % (root / "log" / "slurmd.log"),
        "ProctrackType=proctrack/linuxproc", "TaskPlugin=task/none", "MpiDefault=none",
        "SchedulerType=sched/backfill", "SelectType=select/cons_tres", "SelectTypeParameters=CR_CPU",
        "SchedulerParameters=sched_interval=1", "ReturnToService=2", "JobRequeue=1",
        "JobAcctGatherType=jobacct_gather/none", "AccountingStorageType=accounting_storage/none",
        "InactiveLimit=0", "KillWait=5", "MinJobAge=300",
        "NodeName=%s CPUs=%d RealMemory=1000 State=UNKNOWN" % (host, os.cpu_count() or 1),
        "PartitionName=photonlm Nodes=%s Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:4" % host,
    ]) + "\n")
    env = dict(os.environ, SLURM_CONF=str(conf))
    started = []

    def start(cmd, pid_file):
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, "%s: %s %s" % (cmd[0], r.stdout, r.stderr)
        for _ in range(100):
            if pid_file.exists() and pid_file.read_text().strip():
                started.append(int(pid_file.read_text().split()[0]))
                return
            time.sleep(0.1)
        pytest.fail("%s wrote no pid file (%s)" % (cmd[0], pid_file))

    try:
        start([daemon("munged"), "--force", "-S", str(munge / "sock"), "--key-file=%s" % (munge / "munge.key"),
               "--log-file=%s" % (munge / "log"), "--pid-file=%s" % (munge / "pid"),
               "--seed-file=%s" % (munge / "seed")], munge / "pid")
        start([daemon("slurmctld"), "-c", "-f", str(conf)], root / "slurmctld.pid")
        start([daemon("slurmd"), "-f", str(conf)], root / "slurmd.pid")
        for _ in range(100):
            r = subprocess.run(["sinfo", "-h", "-o", "%T"], env=env, capture_output=True, text=True)
            if r.stdout.strip() == "idle":
                break
            time.sleep(0.2)
        else:
            pytest.fail("the Slurm node did not come up: %s %s\n%s" % (
                r.stdout, r.stderr, (root / "log" / "slurmctld.log").read_text()[-2000:]))
        yield env
    finally:
        for pid in reversed(started):
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        time.sleep(1)


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    folder = tmp_path_factory.mktemp("slurm_scene")
    path = folder / "scene.json"
    path.write_text(json.dumps(SCENE))
    r = subprocess.run([CLI, "bake", str(path), "-o", str(folder / "single")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return path, outputs(folder / "single")


def slurm_bake(env, scene, out, *args, kill=None):
    """kill: "STAGE:K", the task whose first attempt is killed."""
    if kill is not None:
        env = dict(env, PHOTONLM_TEST_KILL=kill)
    return subprocess.run(["bash", SCRIPT, str(scene), "-o", str(out), "--shards", "4", "--wait",
                           "--photonlm", CLI] + list(args), env=env, capture_output=True, text=True, timeout=240)


def test_four_shards_with_one_killed_once_equal_one_machine(slurm, single, tmp_path):
    scene, expected = single
    out = tmp_path / "out"
    r = slurm_bake(slurm, scene, out, kill="shard:2")
    assert r.returncode == 0, r.stdout + r.stderr + (out / "logs" / "merge.log").read_text()
    log = (out / "logs" / "shard-2.log").read_text()
    assert "shard 2 failed (exit 137)" in log and "attempt 2" in log, log
    got = outputs(out)
    for name in expected:
        assert got[name] == expected[name], name


def test_a_shard_that_stays_dead_fails_the_merge_cleanly(slurm, single, tmp_path):
    scene, _ = single
    out = tmp_path / "out"
    r = slurm_bake(slurm, scene, out, "--retries", "0", kill="shard:3")
    assert r.returncode != 0, r.stdout + r.stderr
    merge_log = (out / "logs" / "merge.log").read_text()
    assert "shard(s) 3 of 4 missing" in merge_log, merge_log
    assert sorted(os.listdir(out)) == ["jobs", "logs", "parts"]


def test_rounds_reach_a_target_error(slurm, single, tmp_path):
    scene, _ = single
    out = tmp_path / "out"
    # 4 k photons leave the estimate above 3 %; the next round asks for what 1 / sqrt(photons) needs.
    r = slurm_bake(slurm, scene, out, "--photons", "4000", "--target-error", "0.03", "--max-rounds", "3")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "round 1: error estimate" in r.stdout and "round 2" in r.stdout and "target met" in r.stdout, r.stdout
    report = json.loads((out / "report.json").read_text())
    assert report["target"]["met"] and report["stats"]["error_estimate"] <= 0.03, report
    assert report["settings"]["photon_count"] > 4000


def test_texel_ranges_with_one_gather_killed_once_equal_one_machine(slurm, single, tmp_path):
    """4 shards and 2 texel ranges: the direct arrays run beside the shards, the gather array after both."""
    scene, expected = single
    out = tmp_path / "out"
    r = slurm_bake(slurm, scene, out, "--texel-ranges", "2", kill="gather:1")
    assert r.returncode == 0, r.stdout + r.stderr + (out / "logs" / "merge.log").read_text()
    assert "final gather job array" in r.stdout, r.stdout
    log = (out / "logs" / "gather-1.log").read_text()
    assert "gather 1 failed (exit 137)" in log and "attempt 2" in log, log
    assert "direct 2 of 2, attempt 1" in (out / "logs" / "direct-2.log").read_text()
    assert sorted(os.listdir(out / "parts")) == sorted(
        ["part-%05d-of-00004.plmpart" % k for k in range(1, 5)]
        + ["%s-%05d-of-00002.plmpart" % (kind, k) for kind in ("direct", "gather") for k in (1, 2)])
    got = outputs(out)
    for name in expected:
        assert got[name] == expected[name], name
