//! Fuzzes the PLY (ascii and binary) reader: any input must give Ok or a typed error,
//! never a panic, a hang or an unbounded allocation; an accepted cloud
//! keeps the readers' promises (`checks/cloud.rs`).
#![no_main]

use std::io::Cursor;

use libfuzzer_sys::fuzz_target;
use silva::cloud::{Format, ReadOptions, read_as};

#[path = "../checks/cloud.rs"]
mod checks;
use checks::check_read;

fuzz_target!(|data: &[u8]| {
    // A small limit keeps each run fast; the limit itself is what is tested.
    let opts = ReadOptions {
        max_points: 100_000,
    };
    check_read(read_as(Cursor::new(data), Format::Ply, &opts), &opts);
});
