//! Sans-IO EtherCAT CoE slave for the CiA 402 drive of `drive-protocol`: frames (bytes) and
//! time go in, frames come out; no sockets, threads or clocks inside.
//!
//! - [`frame`]: the Ethernet + EtherCAT header and datagrams, parse and build;
//! - [`esc`]: the slave controller's register space and RAM as a master reads and writes it;
//! - [`datagram`]: every command (APxx, FPxx, Bxx, Lxx, ARMW, FRMW) with auto-increment
//!   addressing and working counters as an ESC counts them;
//! - [`sii`]: the EEPROM image generated from the drive's identity; [`esi`]: the same as the
//!   ESI XML file a master imports;
//! - [`al`]: the INIT / PRE-OP / SAFE-OP / OP / BOOT state machine and its AL status codes;
//! - [`mailbox`] and [`coe`]: SM0 / SM1 mailboxes, CoE SDO, SDO information, emergency;
//! - [`dc`]: distributed clocks: the local clock and its drift control, the SYNC0 unit and
//!   the DC SYNC0 synchronisation type;
//! - [`pdo`]: PDO assignment and the process image through the FMMUs;
//! - [`slave`]: one slave around one drive-core node; [`segment`]: slaves in line order.
//!
//! What is not emulated: EoE, FoE, SoE, port redundancy, the ESC's three-buffer mode (process
//! data has one buffer), SYNC1 and the latch unit. Drift control is a model of the ESC's time
//! control loop ([`dc::DcClock`]), not its gate-level arithmetic. A PDO mapping may be as
//! long as a sync manager buffer ([`pdo::MAX_IMAGE`]), not 8 bytes as on CAN.

#![warn(missing_docs)]

pub mod al;
pub mod coe;
pub mod datagram;
pub mod dc;
pub mod esc;
pub mod esi;
pub mod esi_od;
pub mod frame;
pub mod mailbox;
pub mod pdo;
pub mod segment;
pub mod sii;
pub mod slave;

pub use al::AlState;
pub use segment::Segment;
pub use slave::{Slave, SlaveError};
