//! `--firmware [ELF]` on `host-sim lift` and `host-sim serve`: the same job with the flashed
//! firmware in the loop instead of the core, run by the `fwsim` program (the workspace's
//! `fwsim/`, docs/fwsim.md). fwsim links the Unicorn emulator (GPL-2.0), so host-sim (MIT OR
//! Apache-2.0) does not link it: it runs it as a separate process, with the ELF given or, by
//! default, `scripts/fw-build`'s default image, built when missing.

use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root (host-sim's parent).
fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The ELF to run: `elf`, or scripts/fw-build's default image (built when missing: fw-build
/// prints where it wrote it).
fn elf(elf: Option<PathBuf>) -> Result<PathBuf, Box<dyn Error>> {
    if let Some(e) = elf {
        return Ok(e);
    }
    eprintln!("host-sim: building the firmware (scripts/fw-build) ...");
    let out = Command::new(repo().join("scripts/fw-build")).output()?;
    let log = String::from_utf8_lossy(&out.stderr);
    let built = log
        .lines()
        .find_map(|l| l.strip_prefix("fw-build: built "))
        .and_then(|rest| rest.split(' ').next())
        .map(PathBuf::from);
    match built {
        Some(p) if out.status.success() => Ok(p),
        _ => Err(format!("scripts/fw-build failed:\n{log}").into()),
    }
}

/// The `fwsim` program: beside this executable (same profile), else built with cargo.
fn fwsim() -> Result<PathBuf, Box<dyn Error>> {
    let exe = std::env::current_exe()?;
    let next = exe.with_file_name("fwsim");
    if next.exists() {
        return Ok(next);
    }
    let release = exe.components().any(|c| c.as_os_str() == "release");
    eprintln!("host-sim: building fwsim (cargo build -p fwsim) ...");
    let mut cargo = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    cargo.current_dir(repo()).args(["build", "-p", "fwsim"]);
    if release {
        cargo.arg("--release");
    }
    if !cargo.status()?.success() {
        return Err("cargo build -p fwsim failed".into());
    }
    Ok(next)
}

/// Runs `fwsim <cmd> --elf ELF <args>` and waits for it.
pub fn run(cmd: &str, firmware: Option<PathBuf>, args: &[String]) -> Result<(), Box<dyn Error>> {
    let elf = elf(firmware)?;
    let status = Command::new(fwsim()?)
        .arg(cmd)
        .arg("--elf")
        .arg(&elf)
        .args(args)
        .status()?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("fwsim {cmd} failed ({status})").into())
    }
}
