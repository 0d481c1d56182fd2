//! Fuzzes the LAS and LAZ reader (the header's compression bit picks the
//! decoder): any input must give Ok or a typed error, never a panic, a hang
//! or an unbounded allocation.
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
    check_read(read_as(Cursor::new(data), Format::Las, &opts), &opts);
});
