//! Printing that returns an error on a closed or full stream instead of panicking (`outln!`, `errln!`).

use std::io::{self, Write};

/// Writes to standard output; a closed or full stream is an error (one line, a non-zero exit), never a
/// panic as `print!` would give ([`outln!`](crate::outln)).
pub(crate) fn out_text(args: std::fmt::Arguments) -> crate::error::Result<()> {
    let mut out = io::stdout().lock();
    write!(out, "{args}").and_then(|()| out.flush()).map_err(|e| format!("standard output: {e}").into())
}

/// Writes to standard error (what coevo says besides its results); a closed or full stream is an error,
/// never a panic as `eprintln!` would give ([`errln!`](crate::errln)).
pub(crate) fn err_text(args: std::fmt::Arguments) -> crate::error::Result<()> {
    let mut err = io::stderr().lock();
    write!(err, "{args}").and_then(|()| err.flush()).map_err(|e| format!("standard error: {e}").into())
}

/// `println!` that returns an error instead of panicking on a closed or full standard output.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => { $crate::io::out_text(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `eprintln!` that returns an error instead of panicking on a closed or full standard error.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => { $crate::io::err_text(format_args!("{}\n", format_args!($($arg)*))) };
}
