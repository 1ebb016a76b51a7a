//! Bus captures (candump logs): read a CAN bus recording (can-utils `candump -L`, or `candump -ta`) and decode
//! what one CiA 402 drive reported in its PDOs, with the drive's PDO mapping, into one sample
//! per SYNC: the trace the backlash detector needs, as the reference master would have seen it.
//!
//! Accepted lines (empty lines and `#` comments are skipped):
//! - `candump -L`: `(1700000000.123456) vcan0 185#0102030405060708` (`185#R` remote frame,
//!   8-digit IDs extended or error frames, `##` CAN FD);
//! - `candump -ta` (and can-utils `log2long`): ` (1700000000.123456)  vcan0  185   [8]  01 02 03
//!   04 05 06 07 08`, with an optional `-a` ASCII column, `remote request`, `ERRORFRAME` (its
//!   `-e` detail lines, which start with a tab, are skipped) and CAN FD lengths `[02]`..`[64]`.
//!
//! Remote, error, extended-ID and CAN FD frames are counted and skipped; any other malformed line
//! is an error `file:line: reason`.
//!
//! The PDO mapping of node N starts from the drive's defaults, read from our own object
//! dictionary ([`PdoConfig::from_node`]): COB-IDs 0x1400..0x1403 / 0x1800..0x1803 sub 1,
//! mappings 0x1600..0x1603 / 0x1A00..0x1A03. Expedited SDO downloads to those objects (request
//! on 0x600+N, confirmed by 0x580+N with command 0x60 and the same index and sub) change it; an
//! abort (0x80) leaves the old value; NMT reset node or reset communication (to N or to all)
//! returns it to the defaults. Segmented and block downloads are not followed (counted), and a
//! mapping saved with 0x1010 and restored at reset is not modelled: the defaults come back.
//! The SYNC COB-ID is taken as 0x080.
//!
//! Decoded: TPDO (drive to master) 0x6041 statusword, 0x6061 mode display, 0x6064 position,
//! 0x606C velocity, 0x6077 torque, 0x6078 current, 0x60E4 sub 1 direct encoder, 0x60F4
//! following error, 0x606B velocity demand; RPDO (master to drive) 0x607A target position and
//! 0x60FF target velocity. At every SYNC the latest values form one [`BusSample`].
//!
//! Rows: one per SYNC, the set-points in force at it (received before it) and the values of the
//! drive's synchronous TPDOs that answered it. Answers are taken in order: the first answer
//! after a SYNC answers the oldest SYNC not yet answered (a drive that falls behind, stalled
//! inside user-mode Linux or on a busy host, answers late but in order); after 8 late answers
//! in a row the drive is taken to have lost one, not to be behind.
//!
//! Time base ([`trace::TimeBase`]): a drive on its own clock (a real drive, `run`) samples
//! when a SYNC comes, so row k is at the SYNC's time stamp in the capture (the kernel time of
//! the frame); late and lost SYNCs stay where they happened and the spectra are taken on
//! these uneven times ([`crate::spectrum::WindowSpectra`]). A drive clocked by the
//! SYNC count (`run --lockstep`) moves one period per SYNC however late it comes: row k is at
//! `k * period`, the period from `--sync-period-us`, else a confirmed SDO write to 0x1006
//! (unless the bus disagrees by more than 10 %), else the median SYNC interval. Which one the
//! capture needs is told from the capture ([`trace::choose_time_base`]: do the axis's
//! increments grow with the interval between SYNCs?), or given (`analyze --time-base`).
//!
//! Set velocity (for the constant-velocity windows): in CSP (mode 8) from the 0x607A targets
//! ([`crate::windows::set_velocity_from_demand`]: a PLC's targets are whole units, so a speed
//! of 16.7 units per cycle comes as steps of 16 and 17); in CSV and PV (modes 9, 3) 0x60FF;
//! otherwise 0 (no window). Not 0x606B: in our drive, as in many, the velocity demand is the
//! position controller's output, which carries the limit cycle itself. The mode is the mode
//! display 0x6061, else the last confirmed SDO write to 0x6060.

//!
//! Three stages, one file each: [`candump`] reads the log lines into frames, [`follow`] follows
//! the bus (SDO writes, NMT resets: the PDO mapping in force, the set-points written over SDO)
//! and decodes one [`BusSample`] per SYNC, [`trace`] builds the detector's trace from them.

pub mod candump;
pub mod follow;
pub mod trace;

pub use candump::{looks_like_candump, parse_line, FrameKind, LogFrame};
pub use follow::{
    decode, decode_lines, BusLog, BusSample, DecodeOptions, DecodeStats, LogLines, Object,
    PdoConfig, PdoMapping, PeriodSource, TextLines, SYNC_COB_ID,
};
pub use trace::{choose_time_base, trace_from_candump_with, MissingObjects, TimeBase};
