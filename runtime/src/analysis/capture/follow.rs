//! Following a capture's bus (SDO writes, NMT resets: the PDO mapping in force) is the
//! analysis crate's ([`drive_analysis::capture::follow`], re-exported here); what needs a drive
//! is here: the PDO configuration our drive has after reset ([`DriveDefaults`]).

pub use drive_analysis::capture::follow::*;

/// The PDO configuration our drive has after reset, read from its object dictionary.
pub trait DriveDefaults: Sized {
    /// The defaults of our drive for `preset` as node `node_id`; also whether the axis is
    /// rotary (user unit 0.001 deg) or linear (1 um).
    fn drive_defaults(node_id: u8, preset: &str) -> anyhow::Result<(Self, bool)>;
}

impl DriveDefaults for PdoConfig {
    fn drive_defaults(node_id: u8, preset: &str) -> anyhow::Result<(Self, bool)> {
        let cfg = crate::presets::AxisConfig::from_preset(preset)
            .map_err(|e| anyhow::anyhow!("preset {preset}: {e}"))?;
        let mut drive = crate::drive::axis_drive::AxisDrive::from_config(&cfg)
            .map_err(|e| anyhow::anyhow!("preset {preset}: {e}"))?;
        let info = drive_protocol::Drive::info(&drive);
        let node = crate::drive::node(&mut drive, node_id)?;
        Ok((Self::from_node(&node)?, info.rotary))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defaults() -> PdoConfig {
        PdoConfig::drive_defaults(5, "cnc1").unwrap().0
    }

    #[test]
    fn defaults_come_from_the_drive_object_dictionary() {
        let d = defaults();
        assert_eq!(d.tpdo[0].cob_id, 0x185);
        assert_eq!(d.tpdo[1].mapped(), &[0x6041_0010, 0x6064_0020]);
        assert_eq!(d.rpdo[1].cob_id, 0x305);
        assert_eq!(d.rpdo[1].mapped(), &[0x6040_0010, 0x607A_0020]);
    }

    #[test]
    fn follows_confirmed_remaps_ignores_aborted_ones_and_resets() {
        // Remap TPDO2 (0x285) to velocity only; an aborted attempt to map position is ignored.
        let log = "\
(1.000000) can0 605#2F011A0000000000
(1.000100) can0 585#60011A0000000000
(1.000200) can0 605#23011A012000646000
(1.000300) can0 585#80011A0100000906
(1.000400) can0 605#23011A0120006C60
(1.000500) can0 585#60011A0100000000
(1.000600) can0 605#2F011A0001000000
(1.000700) can0 585#60011A0000000000
(1.001000) can0 285#E8030000
(1.001100) can0 080#
(1.002000) can0 000#8205
(1.002100) can0 285#7856341200100000
(1.002200) can0 080#
";
        // Line 3 has 9 data bytes: a strict parser refuses it, with its line number.
        let opts = DecodeOptions {
            node_id: 5,
            defaults: defaults(),
            sync_period_us: None,
        };
        let e = decode(log, "x.log", &opts).unwrap_err().to_string();
        assert!(e.starts_with("x.log:3:"), "{e}");
        let log = log.replace("605#23011A012000646000", "605#23011A0120006460");
        let r = decode(&log, "x.log", &opts).unwrap();
        assert_eq!(r.stats.sdo_writes_aborted, 1);
        assert_eq!(r.stats.pdo_config_writes, 3);
        assert_eq!(r.samples.len(), 2);
        assert_eq!(r.samples[0].velocity_uu_s, 1000);
        assert_eq!(r.samples[0].position_uu, 0);
        // After reset communication TPDO2 is statusword + position again.
        assert_eq!(r.samples[1].statusword, 0x5678);
        assert_eq!(r.samples[1].position_uu, 0x1000_1234);
        assert_eq!(r.samples[1].velocity_uu_s, 1000);
        assert_eq!(r.period_us, 1100);
        assert_eq!(r.period_source, PeriodSource::MedianSyncInterval);
    }

    #[test]
    fn the_rest_of_an_answer_logged_after_the_next_sync_stays_with_its_sync() {
        // A lock-step master sends SYNC 2 as soon as TPDO2 answered SYNC 1: TPDO3 and TPDO4
        // of SYNC 1 (velocity 0x606C, direct position 0x60E4) are logged after SYNC 2, before
        // the drive's answer to it. Each SYNC's row holds its own answer.
        let log = "\
(1.000000) can0 080#
(1.000100) can0 185#370208
(1.000200) can0 285#3702E8030000
(1.000300) can0 080#
(1.000400) can0 385#37020A000000
(1.000500) can0 485#3702E9030000
(1.000600) can0 185#370208
(1.000700) can0 285#3702D0070000
(1.000800) can0 385#370214000000
(1.000900) can0 485#3702D1070000
";
        let opts = DecodeOptions {
            node_id: 5,
            defaults: defaults(),
            sync_period_us: None,
        };
        let r = decode(log, "x.log", &opts).unwrap();
        assert_eq!(r.rows.len(), 2);
        let row = |k: usize| {
            let s = &r.rows[k];
            (s.position_uu, s.velocity_uu_s, s.direct_position_uu)
        };
        assert_eq!(row(0), (1000, 10, 1001));
        assert_eq!(row(1), (2000, 20, 2001));
        assert!(r.answered.iter().all(|&a| a));
    }

    #[test]
    fn a_lock_step_drive_takes_the_interpolation_period_the_master_wrote() {
        // 0x60C2 = 1 x 10^-3 s written and confirmed; SYNCs every 1.3 ms (a slow master).
        let log = "\
(1.000000) can0 605#2FC2600101000000
(1.000100) can0 585#60C2600100000000
(1.000200) can0 605#2FC26002FD000000
(1.000300) can0 585#60C2600200000000
(1.001000) can0 080#
(1.002300) can0 080#
(1.003600) can0 080#
";
        let opts = DecodeOptions {
            node_id: 5,
            defaults: defaults(),
            sync_period_us: None,
        };
        let r = decode(log, "x.log", &opts).unwrap();
        assert_eq!(
            r.period_us, 1300,
            "the bus' own period is the median interval"
        );
        assert_eq!(r.lockstep_period_us, 1000);
        assert_eq!(r.lockstep_period_source, "0x60C2 written in the log");
        assert!((r.t_s(2) - 0.002).abs() < 1e-12);
        // 0x1006 comes first, as the drive takes it; the command line before both.
        let with_1006 = format!(
            "(0.999000) can0 605#2306100020030000\n(0.999100) can0 585#6006100000000000\n{log}"
        );
        let r = decode(&with_1006, "x.log", &opts).unwrap();
        assert_eq!(
            (r.lockstep_period_us, r.lockstep_period_source),
            (800, "0x1006 written in the log")
        );
        let given = DecodeOptions {
            sync_period_us: Some(2000),
            ..opts
        };
        let r = decode(log, "x.log", &given).unwrap();
        assert_eq!(r.lockstep_period_us, 2000);
    }
}
