//! The firmware image: the loadable segments of the ELF `scripts/fw-build` writes (the bytes a
//! probe flashes: each PT_LOAD segment at its physical address, so `.data`'s initial values land
//! in flash where cortex-m-rt's reset handler copies them from) and the symbols the harness needs.

use object::elf::PT_LOAD;
use object::read::elf::{ElfFile32, ProgramHeader};
use object::{Object, ObjectSymbol};
use std::path::Path;

/// A loaded ELF.
pub struct Image {
    /// The ELF file's bytes (for the defmt table).
    pub bytes: Vec<u8>,
    /// (physical address, bytes) of every loadable segment with file contents.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// Address of defmt-rtt's control block (`_SEGGER_RTT`), if linked.
    pub rtt: Option<u32>,
}

impl Image {
    /// Reads and parses `path`.
    pub fn load(path: &Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(bytes).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Parses an ELF image already in memory.
    pub fn parse(bytes: Vec<u8>) -> Result<Self, String> {
        let elf = ElfFile32::<object::Endianness>::parse(&*bytes).map_err(|e| e.to_string())?;
        if elf.architecture() != object::Architecture::Arm {
            return Err(format!("not an ARM ELF ({:?})", elf.architecture()));
        }
        let endian = elf.endian();
        let mut segments = Vec::new();
        for ph in elf.elf_program_headers() {
            if ph.p_type(endian) != PT_LOAD || ph.p_filesz(endian) == 0 {
                continue;
            }
            let data = ph
                .data(endian, &*bytes)
                .map_err(|()| "bad segment".to_string())?;
            segments.push((ph.p_paddr(endian), data.to_vec()));
        }
        let rtt = elf
            .symbols()
            .find(|s| s.name() == Ok("_SEGGER_RTT"))
            .map(|s| s.address() as u32);
        Ok(Self {
            bytes,
            segments,
            rtt,
        })
    }
}
