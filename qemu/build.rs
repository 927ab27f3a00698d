//! Link settings and the golden vectors for the QEMU program.
//!
//! - `memory.x` (mps2-an386) sits in this crate's root, which is the linker's working
//!   directory: lld's `INCLUDE memory.x` looks there before the search path, where liftfw's own
//!   build script has put the STM32 memory map.
//! - `LIFTFW_GOLDEN` names the vector file (`scripts/qemu-test` generates it with `golden-gen`);
//!   it is embedded with `include_bytes!`.
use std::env;
use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-env-changed=LIFTFW_GOLDEN");
    let golden = env::var("LIFTFW_GOLDEN")
        .map_err(|_| "set LIFTFW_GOLDEN to the golden-vector file (scripts/qemu-test does)")?;
    println!("cargo:rerun-if-changed={golden}");
    println!("cargo:rustc-env=LIFTFW_GOLDEN_FILE={golden}");
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    Ok(())
}
