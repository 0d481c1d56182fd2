//! Containment of panics inside the third-party LAS/LAZ decoders.
//!
//! The `laz` crate's arithmetic decoder trusts the entropy-coded stream: a
//! corrupt LAZ file can make it index past a probability table and panic
//! (found by `cargo fuzz run las`; laz 0.12, `ArithmeticDecoder::decode_symbol`).
//! Such bytes cannot be rejected up front, since only decoding reveals them,
//! so the decoder runs under [`contain`], which turns a panic into an error.
//!
//! A panic hook is process-global, so [`contain`] installs, once, a hook that
//! wraps the previous one: on a thread currently inside [`contain`] it keeps
//! the panic message for the error instead of printing it; everywhere else it
//! defers to the previous hook unchanged.

use std::cell::{Cell, RefCell};
use std::panic::{AssertUnwindSafe, PanicHookInfo};
use std::sync::Once;

thread_local! {
    static CONTAINED: Cell<bool> = const { Cell::new(false) };
    static MESSAGE: RefCell<Option<String>> = const { RefCell::new(None) };
}

static INSTALL_HOOK: Once = Once::new();

/// Runs `f`; a panic inside it becomes `Err(message)`.
pub(super) fn contain<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    INSTALL_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if CONTAINED.with(Cell::get) {
                MESSAGE.with(|m| *m.borrow_mut() = Some(describe(info)));
            } else {
                previous(info);
            }
        }));
    });
    let outer = CONTAINED.with(|c| c.replace(true));
    // Unwind safety: on a panic the caller discards everything `f` touched
    // (decoder, buffers, partial cloud) and returns an error.
    let result = std::panic::catch_unwind(AssertUnwindSafe(f));
    CONTAINED.with(|c| c.set(outer));
    result.map_err(|_| {
        MESSAGE
            .with(|m| m.borrow_mut().take())
            .unwrap_or_else(|| "the decoder failed".to_owned())
    })
}

/// The panic payload as one line.
fn describe(info: &PanicHookInfo<'_>) -> String {
    let payload = info.payload();
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "the decoder failed".to_owned())
        .replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::contain;

    #[test]
    fn a_panic_becomes_an_error_with_its_message() {
        let v: Vec<u8> = Vec::new();
        let index = v.len() + 3;
        let err = contain(|| v[index]).unwrap_err();
        assert!(err.contains("index out of bounds"), "{err}");
        assert_eq!(contain(|| 7), Ok(7));
    }
}
