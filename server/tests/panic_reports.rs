//! A fault that repeats does not flood stderr: with the hook `rigcast` installs at start, a
//! panic repeated at one place (a target retried every 250 ms for a minute: 240 panics) prints
//! one standard report, and a panic at another place is still reported at once. Run in a child
//! process (this test executable again), since a panic hook is process-wide, and judged on
//! the child's real stderr.
#![allow(clippy::unwrap_used)]

const CHILD: &str = "RIGCAST_PANIC_REPORTS_CHILD";

fn panic_at_one_place(k: usize) {
    panic!("repeated fault {k}");
}

fn panic_at_another_place() {
    panic!("another fault");
}

#[test]
fn a_panic_repeated_every_retry_prints_one_report() {
    if std::env::var_os(CHILD).is_some() {
        rigcast_server::panic_reports::install();
        for k in 0..240 {
            assert!(std::panic::catch_unwind(|| panic_at_one_place(k)).is_err());
        }
        for _ in 0..3 {
            assert!(std::panic::catch_unwind(panic_at_another_place).is_err());
        }
        return;
    }
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "a_panic_repeated_every_retry_prints_one_report",
            "--exact",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env(CHILD, "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "child failed: {stderr}");
    let reports: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("panicked at"))
        .collect();
    println!(
        "child stderr: {} lines, reports: {reports:?}",
        stderr.lines().count()
    );
    assert_eq!(reports.len(), 2, "{stderr}");
    assert_eq!(
        stderr.matches("repeated fault").count(),
        1,
        "the repeated panic printed more than once: {stderr}"
    );
    assert_eq!(stderr.matches("another fault").count(), 1, "{stderr}");
}
