//! One look for every progress bar of the CLI.

use indicatif::{ProgressBar, ProgressStyle};

pub fn bar(total: u64, unit: &str) -> ProgressBar {
    ProgressBar::new(total).with_style(
        ProgressStyle::with_template(&format!(
            "{{bar:40}} {{pos}}/{{len}} {unit} [{{elapsed_precise}} < {{eta}}] {{msg}}"
        ))
        .expect("valid template"),
    )
}
