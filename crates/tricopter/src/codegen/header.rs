//! The C header of kestrel-ffi (`crates/ffi/include/kestrel.h`), generated
//! by cbindgen from the crate's sources and its `cbindgen.toml`.
//!
//! cbindgen is used as a library, reading the sources directly
//! (`Builder::with_src`, no `cargo metadata` run and no macro expansion),
//! so the header is a pure function of the files under `crates/ffi`.

use super::file::{CodegenError, GeneratedFile};
use std::path::Path;

/// Where the header goes.
pub const HEADER: &str = "crates/ffi/include/kestrel.h";

/// The crate root cbindgen starts from (it follows the `mod` items).
pub const FFI_LIB: &str = "crates/ffi/src/lib.rs";

/// The cbindgen configuration.
pub const FFI_CONFIG: &str = "crates/ffi/cbindgen.toml";

/// kestrel-ffi's header, generated from the sources under `root`.
///
/// # Errors
/// [`CodegenError::Header`] when cbindgen cannot read the configuration
/// or the sources.
pub fn header_file(root: &Path) -> Result<GeneratedFile, CodegenError> {
    let fail = |e: &dyn std::fmt::Display| CodegenError::Header(e.to_string());
    let config = cbindgen::Config::from_file(root.join(FFI_CONFIG)).map_err(|e| fail(&e))?;
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(root.join(FFI_LIB))
        .generate()
        .map_err(|e| fail(&e))?;
    let mut out = Vec::new();
    bindings.write(&mut out);
    let contents = String::from_utf8(out).map_err(|e| fail(&e))?;
    Ok(GeneratedFile {
        path: HEADER,
        contents,
        generator: "cbindgen over crates/ffi/src with crates/ffi/cbindgen.toml",
    })
}
