use std::process::ExitCode;

fn main() -> ExitCode {
    // Any panic is a bug; say so on one line instead of a backtrace dump.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("mocomp: internal error (a bug, please report it): {msg}{at}");
    }));
    mocomp::cli::main()
}
