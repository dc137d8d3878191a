//! A minimal stderr logger for the `log` facade.

use log::{Level, LevelFilter, Metadata, Record};

struct StderrLogger;

static LOGGER: StderrLogger = StderrLogger;

impl log::Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &Record<'_>) {
        if self.enabled(record.metadata()) {
            let tag = match record.level() {
                Level::Error => "error",
                Level::Warn => "warning",
                Level::Info => "info",
                Level::Debug => "debug",
                Level::Trace => "trace",
            };
            // (Not eprintln!, which panics when stderr is closed or full.)
            crate::errln!("{tag}: {}", record.args());
        }
    }

    fn flush(&self) {}
}

/// Installs the logger (idempotent). `verbose`: info and up, else warnings and errors.
pub fn init(verbose: bool) {
    let _ = log::set_logger(&LOGGER);
    log::set_max_level(if verbose { LevelFilter::Info } else { LevelFilter::Warn });
}
