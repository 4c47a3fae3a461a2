//! The command line's names for the library's choice enums. The library types
//! ([`GnssFormat`], [`Pace`]) implement `FromStr`/`Display` and do not depend on clap;
//! these mirrors derive [`clap::ValueEnum`] so that `--help` lists each value with its
//! meaning, and convert into the library type once parsed.

use vgps_replay::drive::gnss::GnssFormat;
use vgps_replay::live::Pace;

/// `--gnss-format`: the formats of a satellite GPS file ([`GnssFormat`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GnssFormatArg {
    /// NMEA 0183 sentences (`GGA`, `RMC`, `HDT`).
    Nmea,
    /// GPX 1.0 or 1.1 track points (`trkpt`).
    Gpx,
    /// NCLT `gps.csv`: `utime,mode,num_sats,lat,lng,alt,track,speed`, no header.
    Nclt,
    /// u-blox UBX binary (`NAV-PVT`) mixed with NMEA, as u-blox receivers log.
    Ubx,
}

impl From<GnssFormatArg> for GnssFormat {
    fn from(a: GnssFormatArg) -> Self {
        match a {
            GnssFormatArg::Nmea => Self::Nmea,
            GnssFormatArg::Gpx => Self::Gpx,
            GnssFormatArg::Nclt => Self::Nclt,
            GnssFormatArg::Ubx => Self::Ubx,
        }
    }
}

/// `--pace`: how fast a replay feeds its live outputs ([`Pace`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum PaceArg {
    /// At the drive's own time: a frame is sent no earlier than its time after the first
    /// frame's (as a receiver would send it); never waits when localizing is slower.
    #[default]
    Real,
    /// As fast as frames are localized.
    Fast,
}

impl From<PaceArg> for Pace {
    fn from(a: PaceArg) -> Self {
        match a {
            PaceArg::Real => Self::Real,
            PaceArg::Fast => Self::Fast,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    /// The names clap accepts, in order.
    fn names<T: ValueEnum>() -> Vec<String> {
        T::value_variants()
            .iter()
            .map(|v| v.to_possible_value().unwrap().get_name().to_owned())
            .collect()
    }

    /// The command line's names are the library's (`FromStr`/`Display`), one for one, and
    /// each converts to the library value of that name.
    #[test]
    fn names_match_the_library() {
        let lib: Vec<String> = GnssFormat::ALL.iter().map(|f| f.to_string()).collect();
        assert_eq!(names::<GnssFormatArg>(), lib);
        for a in GnssFormatArg::value_variants() {
            let name = a.to_possible_value().unwrap().get_name().to_owned();
            assert_eq!(name.parse::<GnssFormat>(), Ok(GnssFormat::from(*a)));
        }
        let lib: Vec<String> = Pace::ALL.iter().map(|p| p.to_string()).collect();
        assert_eq!(names::<PaceArg>(), lib);
        for a in PaceArg::value_variants() {
            let name = a.to_possible_value().unwrap().get_name().to_owned();
            assert_eq!(name.parse::<Pace>(), Ok(Pace::from(*a)));
        }
        assert_eq!(Pace::from(PaceArg::default()), Pace::default());
    }
}
