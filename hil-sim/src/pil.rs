//! Processor in the loop: the drive runs on an emulated Cortex-M4F (QEMU `mps2-an386`,
//! program `qemu-target/src/bin/pil.rs`), the plant here; one link frame each way per PWM
//! period, in lockstep.
//!
//! Channel: two FIFOs in a fresh temporary directory, `to_mcu` and `from_mcu`, which the
//! target opens with semihosting `SYS_OPEN` (QEMU runs with that directory as its working
//! directory). Frames are [`controller_core::link`] frames, the same as the firmware's UART
//! link. Measurements and outputs cross as IEEE-754 bits, so with the same f32 operations
//! and the same `libm` on both sides the trace equals the in-process SIL trace bit for bit
//! (asserted in `tests/pil.rs`).
//!
//! Speed: every round trip is two semihosting calls on the target and a write and a read
//! here, each of which wakes the other process. With QEMU and the calling thread on one CPU
//! (the default, [`PilOptions::pin_cpu`]; `sched_setaffinity` through `nix`) a wake-up is a context switch
//! instead of a cross-CPU hand-off, several times faster.
//!
//! Opening a FIFO blocks until the other side opens it; the opens run on a helper thread
//! while this one watches QEMU, so a target that dies at start-up is an error, not a hang.

use crate::link_client::LinkClient;
use crate::sim::DriveUnderTest;
use controller_core::drive::{DriveSpec, FastOutput, Measurements, Mode, PhaseCommand, Reference, Telemetry};
use controller_core::link::{Command, LinkStats, Reply};
use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
use nix::sys::stat::Mode as FileMode;
use nix::unistd::{Pid, mkfifo};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Command as Process, Stdio};
use std::time::{Duration, Instant};

/// Where `cargo xtask qemu` (or `cargo build --release --target thumbv7em-none-eabihf --bin
/// pil` in `qemu-target/`, a workspace of its own) puts the target program; overridden by
/// `--elf` or `HIL_SIM_PIL_ELF`.
pub fn default_elf() -> PathBuf {
    if let Some(p) = std::env::var_os("HIL_SIM_PIL_ELF") {
        return PathBuf::from(p);
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../qemu-target/target/thumbv7em-none-eabihf/release/pil")
}

/// The QEMU executable (`QEMU_SYSTEM_ARM` overrides).
fn qemu_binary() -> String {
    std::env::var("QEMU_SYSTEM_ARM").unwrap_or_else(|_| "qemu-system-arm".into())
}

/// How to run the emulated MCU.
#[derive(Clone, Debug, PartialEq)]
pub struct PilOptions {
    /// The `pil` target program.
    pub elf: PathBuf,
    /// Pin QEMU and the calling thread to this CPU (`None`: leave scheduling alone).
    pub pin_cpu: Option<usize>,
}

impl Default for PilOptions {
    fn default() -> Self {
        Self { elf: default_elf(), pin_cpu: Some(0) }
    }
}

/// Pin the calling thread to `cpu`; returns its previous CPU set to restore. A process
/// spawned from this thread inherits the pinning (`sched_setaffinity(2)`).
fn pin_thread(cpu: usize) -> Option<CpuSet> {
    let this = Pid::from_raw(0);
    let before = sched_getaffinity(this).ok()?;
    let mut one = CpuSet::new();
    one.set(cpu).ok()?;
    sched_setaffinity(this, &one).ok()?;
    Some(before)
}

fn restore_thread(cpus: &CpuSet) {
    let _ = sched_setaffinity(Pid::from_raw(0), cpus);
}

/// A drive on the emulated MCU.
#[derive(Debug)]
pub struct Pil {
    /// The calling thread's CPU set before it was pinned, to restore.
    restore_affinity: Option<CpuSet>,
    qemu: Child,
    dir: PathBuf,
    link: LinkClient<File, File>,
    slow_divider: u16,
    /// Error of the last step, until taken ([`DriveUnderTest::take_failure`]).
    failure: Option<String>,
    /// The signals the target sent with its last `Output`.
    telemetry: Telemetry,
}

impl Pil {
    /// Start QEMU with `opts.elf` and configure its drive with `spec` (validated on the
    /// target).
    pub fn start(opts: &PilOptions, spec: &DriveSpec) -> Result<Self, String> {
        let mut pil = Self::launch(opts)?;
        pil.slow_divider = spec.slow_divider;
        match pil.transact(&Command::Configure(*spec))? {
            Reply::Ack => Ok(pil),
            other => Err(format!("target refused the drive specification: {other:?}")),
        }
    }

    /// Start QEMU with `opts.elf`, nothing configured yet (a commissioning sequence is
    /// started with `Command::Commission`).
    pub fn launch(opts: &PilOptions) -> Result<Self, String> {
        let elf = &opts.elf;
        if !elf.is_file() {
            return Err(format!(
                "target program {} not found: build it with `cargo xtask qemu` (or `cargo build \
                 --release --target thumbv7em-none-eabihf --bin pil` in qemu-target/)",
                elf.display()
            ));
        }
        let dir = fresh_dir()?;
        for name in ["to_mcu", "from_mcu"] {
            if let Err(e) = mkfifo(&dir.join(name), FileMode::S_IRUSR | FileMode::S_IWUSR) {
                let _ = std::fs::remove_dir_all(&dir);
                return Err(format!("cannot make the FIFO {}: {e}", dir.join(name).display()));
            }
        }
        let log = File::create(dir.join("qemu.log")).map_err(|e| format!("cannot create qemu.log: {e}"))?;
        let log2 = log.try_clone().map_err(|e| e.to_string())?;
        // Pin this thread first (remembering its CPUs): QEMU, spawned from it, inherits the
        // pinning and runs on the same CPU.
        let restore_affinity = opts.pin_cpu.and_then(pin_thread);
        let restore = |r: &Option<CpuSet>| {
            if let Some(cpus) = r {
                restore_thread(cpus);
            }
        };
        let mut launcher = Process::new(qemu_binary());
        let spawned = launcher
            .args(["-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic"])
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(elf)
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log2)
            .spawn();
        let mut qemu = match spawned {
            Ok(c) => c,
            Err(e) => {
                restore(&restore_affinity);
                return Err(format!("cannot start {}: {e} (install qemu-system-arm)", qemu_binary()));
            }
        };
        let (to_mcu, from_mcu) = match open_fifos(&dir, &mut qemu) {
            Ok(f) => f,
            Err(e) => {
                restore(&restore_affinity);
                let _ = qemu.kill();
                let _ = qemu.wait();
                let _ = std::fs::remove_dir_all(&dir);
                return Err(e);
            }
        };
        Ok(Pil {
            restore_affinity,
            qemu,
            dir,
            link: LinkClient::new(from_mcu, to_mcu),
            slow_divider: 1,
            failure: None,
            telemetry: Telemetry::default(),
        })
    }

    /// Whether QEMU and the calling thread share one CPU.
    pub fn pinned(&self) -> bool {
        self.restore_affinity.is_some()
    }

    /// Round trips so far.
    pub fn round_trips(&self) -> u64 {
        self.link.round_trips()
    }

    /// Counters of the host-side receiver.
    pub fn stats(&self) -> LinkStats {
        self.link.stats()
    }

    /// Send `cmd`, wait for its reply.
    pub fn transact(&mut self, cmd: &Command) -> Result<Reply, String> {
        self.link.transact(cmd).map_err(|e| format!("{e}{}", self.qemu_log()))
    }

    /// Write raw bytes to the target (for link tests: corrupt frames, noise).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.link.send_raw(bytes).map_err(|e| format!("link to the target broken: {e}"))
    }

    fn qemu_log(&self) -> String {
        match std::fs::read_to_string(self.dir.join("qemu.log")) {
            Ok(s) if !s.trim().is_empty() => format!("; QEMU said: {}", s.trim()),
            _ => String::new(),
        }
    }

    fn expect_ack(&mut self, cmd: &Command) -> Result<(), String> {
        match self.transact(cmd)? {
            // A refusal is the drive's answer, as `Drive::enable` returning Err in the SIL.
            Reply::Ack | Reply::Nack(_) => Ok(()),
            other => Err(format!("unexpected reply {other:?} to {cmd:?}")),
        }
    }
}

impl DriveUnderTest for Pil {
    fn slow_divider(&self) -> u16 {
        self.slow_divider
    }

    fn enable(&mut self) -> Result<(), String> {
        self.expect_ack(&Command::Enable)
    }

    fn set_reference(&mut self, r: Reference) -> Result<(), String> {
        self.expect_ack(&Command::SetReference(r))
    }

    fn controlled_stop(&mut self) -> Result<(), String> {
        self.expect_ack(&Command::Stop)
    }

    fn step(&mut self, m: &Measurements) -> FastOutput {
        let failure = match self.transact(&Command::Step(*m)) {
            Ok(Reply::Output(o, t)) => {
                self.telemetry = t;
                return o;
            }
            Ok(other) => format!("unexpected reply {other:?} to a step"),
            Err(e) => e,
        };
        self.failure = Some(failure);
        self.telemetry = Telemetry::default();
        FastOutput { phases: PhaseCommand::Off, mode: Mode::Idle, brake: false }
    }

    fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    fn take_failure(&mut self) -> Option<String> {
        self.failure.take()
    }
}

impl Drop for Pil {
    fn drop(&mut self) {
        // Closing to_mcu makes the target read end-of-file and exit; kill it if it does not.
        let deadline = Instant::now() + Duration::from_secs(2);
        if let (Ok(r), Ok(w)) = (File::open("/dev/null"), File::create("/dev/null")) {
            self.link = LinkClient::new(r, w);
        }
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.qemu.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
        if let Some(cpus) = &self.restore_affinity {
            restore_thread(cpus);
        }
    }
}

fn fresh_dir() -> Result<PathBuf, String> {
    static COUNTER: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("hil-sim-pil-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    Ok(dir)
}

/// Open both FIFOs (in the target's order: to_mcu, then from_mcu) on a helper thread; fail
/// if QEMU exits first or nothing happens within 20 s.
fn open_fifos(dir: &Path, qemu: &mut Child) -> Result<(File, File), String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let d = dir.to_path_buf();
    std::thread::spawn(move || {
        let r = (|| -> std::io::Result<(File, File)> {
            let to = std::fs::OpenOptions::new().write(true).open(d.join("to_mcu"))?;
            let from = File::open(d.join("from_mcu"))?;
            Ok((to, from))
        })();
        let _ = tx.send(r);
    });
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match rx.recv_timeout(Duration::from_millis(10)) {
            Ok(Ok(files)) => return Ok(files),
            Ok(Err(e)) => return Err(format!("cannot open the link FIFOs: {e}")),
            Err(_) => {}
        }
        let log = || std::fs::read_to_string(dir.join("qemu.log")).unwrap_or_default();
        if let Ok(Some(st)) = qemu.try_wait() {
            unblock(dir);
            return Err(format!("QEMU exited ({st}) before opening the link: {}", log().trim()));
        }
        if Instant::now() > deadline {
            unblock(dir);
            return Err(format!("the target did not open the link within 20 s: {}", log().trim()));
        }
    }
}

/// Open the far ends so a helper thread blocked in `open` returns (and is dropped).
fn unblock(dir: &Path) {
    let d = dir.to_path_buf();
    std::thread::spawn(move || {
        let _r = File::open(d.join("to_mcu"));
        let _w = std::fs::OpenOptions::new().write(true).open(d.join("from_mcu"));
    });
    std::thread::sleep(Duration::from_millis(20));
}
