//! Link settings for the embassy firmware, applied only when building for a bare-metal target.
//!
//! Host builds (`cargo test`, host-sim) see nothing of this: the link arguments are
//! emitted only when `CARGO_CFG_TARGET_OS` is `none`, and only for binaries
//! (`rustc-link-arg-bins`), so the library and its tests stay untouched.

use std::env;
use std::error::Error;
use std::fs;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn Error>> {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=liftfw.x");
    // `liftfw_speed_attr`: the bare-metal build may use `#[optimize(speed)]` on the control
    // tick (an unstable attribute: only where the compiler allows unstable features, i.e. the
    // Debian route's RUSTC_BOOTSTRAP=1; docs/qemu.md "Optimisation level").
    println!("cargo:rustc-check-cfg=cfg(liftfw_speed_attr)");
    println!("cargo:rerun-if-env-changed=RUSTC_BOOTSTRAP");

    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return Ok(());
    }
    if env::var_os("RUSTC_BOOTSTRAP").is_some() {
        println!("cargo:rustc-cfg=liftfw_speed_attr");
    }

    // cortex-m-rt's `link.x` INCLUDEs `memory.x`: put ours where the linker searches,
    // so that an edit of memory.x relinks (knurling app-template style).
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo sets OUT_DIR for build scripts")?);
    fs::copy("memory.x", out.join("memory.x"))?;
    fs::copy("liftfw.x", out.join("liftfw.x"))?;
    println!("cargo:rustc-link-search={}", out.display());

    // `--nmagic`: no page alignment of sections, which saves flash padding.
    println!("cargo:rustc-link-arg-bins=--nmagic");
    // cortex-m-rt's vector table, reset handler and memory layout, through liftfw.x: its
    // `link.x` with the device interrupt table cut after the last interrupt the firmware uses
    // (src/board/vectors.rs).
    println!("cargo:rustc-link-arg-bins=-Tliftfw.x");
    // defmt: the interned-string section the host decoder reads back from the ELF.
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    Ok(())
}
