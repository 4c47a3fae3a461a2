//! UTC calendar time from Unix seconds (proleptic Gregorian calendar, no leap seconds).

/// Seconds per day.
const SECONDS_PER_DAY: i64 = 86_400;

/// The Julian day number of 1970-01-01.
const UNIX_EPOCH_JULIAN_DAY: i64 = 2_440_588;

/// Days since 1970-01-01 of a proleptic Gregorian date; `None` for a date that does not
/// exist (month 13, 31 February, …) or lies beyond the `time` crate's ±999,999 years.
pub(crate) fn days_from_date(year: i64, month: u32, day: u32) -> Option<i64> {
    let month = time::Month::try_from(u8::try_from(month).ok()?).ok()?;
    let date =
        time::Date::from_calendar_date(i32::try_from(year).ok()?, month, u8::try_from(day).ok()?)
            .ok()?;
    Some(i64::from(date.to_julian_day()) - UNIX_EPOCH_JULIAN_DAY)
}

/// The civil date `(year, month 1–12, day 1–31)` of a day count since 1970-01-01; `None`
/// beyond the `time` crate's ±999,999 years.
pub(crate) fn date_from_days(days: i64) -> Option<(i64, u32, u32)> {
    let julian = i32::try_from(days.checked_add(UNIX_EPOCH_JULIAN_DAY)?).ok()?;
    let date = time::Date::from_julian_day(julian).ok()?;
    Some((
        i64::from(date.year()),
        u32::from(u8::from(date.month())),
        u32::from(date.day()),
    ))
}

/// A UTC time split into calendar fields, rounded to `10^-decimals` s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct UtcTime {
    pub year: i64,
    pub month: u32,
    pub day: u32,
    pub hour: u32,
    pub minute: u32,
    pub second: u32,
    /// The fraction of the second in units of `10^-decimals` s.
    pub fraction: u64,
}

/// Splits Unix seconds into UTC fields, rounding to `decimals` (0–6) decimal places of a
/// second first (so that 59.999 s never prints as 60). `None` for non-finite times or times
/// beyond ±10¹² s.
pub(crate) fn utc_fields(time_s: f64, decimals: u32) -> Option<UtcTime> {
    const MAX_ABS_TIME_S: f64 = 1e12;
    if !time_s.is_finite() || time_s.abs() > MAX_ABS_TIME_S {
        return None;
    }
    let scale = 10_i64.pow(decimals.min(6));
    let ticks = (time_s * scale as f64).round() as i64;
    let secs = ticks.div_euclid(scale);
    let fraction = ticks.rem_euclid(scale) as u64;
    let days = secs.div_euclid(SECONDS_PER_DAY);
    let sod = secs.rem_euclid(SECONDS_PER_DAY);
    let (year, month, day) = date_from_days(days)?;
    Some(UtcTime {
        year,
        month,
        day,
        hour: (sod / 3600) as u32,
        minute: (sod / 60 % 60) as u32,
        second: (sod % 60) as u32,
        fraction,
    })
}

/// The ISO 8601 / RFC 3339 UTC form of Unix seconds, with millisecond precision:
/// `YYYY-MM-DDThh:mm:ss.sssZ`. `None` for a non-finite time or beyond ±10¹² s.
///
/// # Example
/// ```
/// use vgps_replay::report::utc_iso8601;
/// assert_eq!(utc_iso8601(0.0).as_deref(), Some("1970-01-01T00:00:00.000Z"));
/// assert_eq!(
///     utc_iso8601(1_700_000_000.1234).as_deref(),
///     Some("2023-11-14T22:13:20.123Z")
/// );
/// assert_eq!(utc_iso8601(f64::NAN), None);
/// ```
pub fn utc_iso8601(time_s: f64) -> Option<String> {
    let t = utc_fields(time_s, 3)?;
    Some(format!(
        "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z",
        t.year, t.month, t.day, t.hour, t.minute, t.second, t.fraction
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(date_from_days(0), Some((1970, 1, 1)));
        assert_eq!(date_from_days(-1), Some((1969, 12, 31)));
        // 2000-02-29 is day 11016; 2024-03-01 is day 19783.
        assert_eq!(date_from_days(11_016), Some((2000, 2, 29)));
        assert_eq!(date_from_days(19_783), Some((2024, 3, 1)));
        for days in [-719_468, -1, 0, 59, 10_957, 20_454, 30_000] {
            let (y, m, d) = date_from_days(days).unwrap();
            assert_eq!(days_from_date(y, m, d), Some(days));
        }
        assert_eq!(days_from_date(2000, 3, 1), Some(11_017));
        // Dates that do not exist.
        assert_eq!(days_from_date(2022, 2, 31), None);
        assert_eq!(days_from_date(2023, 2, 29), None);
        assert_eq!(days_from_date(2022, 4, 31), None);
        assert_eq!(days_from_date(2022, 13, 1), None);
        // Rounding carries into the next day.
        let t = utc_fields(86_399.996, 2).unwrap();
        assert_eq!(
            (t.day, t.hour, t.minute, t.second, t.fraction),
            (2, 0, 0, 0, 0)
        );
    }
}
