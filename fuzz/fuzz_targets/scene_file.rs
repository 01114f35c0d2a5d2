#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    deepcontact_fuzz_harness::scene_file(data);
});
