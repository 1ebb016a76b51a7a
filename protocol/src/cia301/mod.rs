//! CiA 301 communication services, one file per service.

pub mod cob_id;
pub mod emcy;
pub mod emcy_code;
pub mod heartbeat;
pub mod nmt;
pub mod pdo;
pub mod sdo;
pub(crate) mod store;
pub mod sync;
