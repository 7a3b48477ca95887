//! Case files: any text is accepted or rejected with a message, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use membrane_contact::case::Case;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(case) = Case::parse(text, "fuzz", std::path::PathBuf::new()) {
            let _ = case.inputs();
        }
    }
});
