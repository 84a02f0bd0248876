//! The names of the files the viewer writes or downloads: stamped with the time, UTC, and
//! never over an existing file.

use std::path::{Path, PathBuf};

use web_time::{SystemTime, UNIX_EPOCH};

/// `dfsph2d-YYYYMMDD-HHMMSS.EXT` (UTC) in `dir`, with `-2`, `-3`, ... appended when taken.
pub fn timestamped_file(dir: &Path, ext: &str) -> PathBuf {
    let stem = format!("dfsph2d-{}", utc_stamp_now());
    let mut path = dir.join(format!("{stem}.{ext}"));
    let mut k = 2;
    while path.exists() {
        path = dir.join(format!("{stem}-{k}.{ext}"));
        k += 1;
    }
    path
}

/// `YYYYMMDD-HHMMSS` now, UTC: the stamp in the names of the files the viewer writes or
/// downloads.
pub(crate) fn utc_stamp_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc_stamp(secs)
}

/// `YYYYMMDD-HHMMSS` for seconds since the Unix epoch, UTC.
pub(crate) fn utc_stamp(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}{month:02}{day:02}-{:02}{:02}{:02}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_stamps_match_known_dates() {
        assert_eq!(utc_stamp(0), "19700101-000000");
        assert_eq!(utc_stamp(951_782_400), "20000229-000000");
        assert_eq!(utc_stamp(1_700_000_000), "20231114-221320");
    }
}
