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

    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return Ok(());
    }

    // cortex-m-rt's `link.x` INCLUDEs `memory.x`: put ours where the linker searches,
    // so that an edit of memory.x relinks (knurling app-template style).
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo sets OUT_DIR for build scripts")?);
    fs::copy("memory.x", out.join("memory.x"))?;
    println!("cargo:rustc-link-search={}", out.display());

    // `--nmagic`: no page alignment of sections (flash is not paged memory).
    println!("cargo:rustc-link-arg-bins=--nmagic");
    // cortex-m-rt's vector table (with the PAC's full device table), reset handler and memory
    // layout.
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // defmt: the interned-string section the host decoder reads back from the ELF.
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    Ok(())
}
