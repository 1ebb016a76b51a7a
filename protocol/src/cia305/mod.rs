//! LSS slave (CiA 305, Layer Setting Services): lets a master find the drive by its identity,
//! give it a node-ID and a bit timing, and have it store them. Sans-IO and without
//! allocation: [`LssSlave::handle`] takes a received frame and gives back the response to send
//! (on 0x7E4) and an [`LssEvent`] for what the node or the emulator must do.
//!
//! What this slave implements, from CiA 305 as public sources describe it (vendor manuals:
//! maxon EPOS4 communication guide, TR-Electronic, Gefran, Festo) and from the slaves of
//! CANopenNode (`305/CO_LSSslave.c`) and Lely (`src/co/lss.c`), checked against python
//! canopen's master (`canopen/lss.py`, canopen 2.4.1):
//!
//! **Node-IDs.** The *active* node-ID is the one the node uses on the bus (`None`: 0xFF,
//! non-configured: the node sends nothing but LSS answers). The *pending* node-ID is what
//! configure node-ID set; it becomes active at the next NMT reset communication
//! ([`LssSlave::reset_communication`]). The *stored* node-ID is what store configuration
//! wrote to non-volatile memory; it becomes pending (and so active) at NMT reset node and at
//! power-on ([`LssSlave::reset_node`], [`LssSlave::new`]). The bit timing has the same
//! three copies. Valid node-IDs are 1..=127 and 0xFF (unconfigure); anything else is answered
//! with error 1 and changes nothing.
//!
//! **States.** Power-on and every NMT reset put the slave in LSS *waiting* state. Switch state
//! global (0x04) moves every slave between waiting and *configuration*; switch state
//! selective (0x40..=0x43) moves only the slave whose four address parts (0x1018:1..=4) match,
//! sent in that order (a part that differs or comes out of order ends the sequence; 0x40
//! always starts one, as in Lely) and answers 0x44; a finished fastscan moves the slave it
//! found. In configuration state the slave takes configure node-ID (0x11), configure bit
//! timing (0x13), activate bit timing (0x15), store configuration (0x17) and the inquiries
//! (0x5A..=0x5E); in waiting state it ignores them. Switch selective and fastscan work in
//! waiting state only (in configuration state they are ignored, as in Lely). Identify remote
//! slave (0x46..=0x4B, in order; answered 0x4F when vendor-ID and product code are equal and
//! revision and serial number lie in the inclusive ranges) and identify non-configured remote
//! slave (0x4C, answered 0x50 when active and pending node-ID are both 0xFF) work in both
//! states.
//!
//! **Booting with a node-ID given by LSS.** When a non-configured slave (active node-ID 0xFF)
//! with a pending node-ID is switched from configuration back to waiting, it performs an NMT
//! reset communication on its own (CANopenNode; CiA 305) and boots with that node-ID
//! ([`LssEvent::ResetCommunication`]). A configured slave does not: its new node-ID waits for
//! the master's NMT reset (CANopenNode issue 347; Lely does the same for every slave).
//!
//! **Store configuration** writes the pending node-ID and bit timing (not the active ones) to
//! non-volatile memory: the slave reports [`LssEvent::StoreRequested`] and answers once the
//! owner has written them ([`LssSlave::store_done`]: error 0, or 2 when the medium failed).
//! A slave built without storage ([`LssSlave::set_store_supported`]) answers error 1.
//!
//! **Bit timing.** Configure bit timing accepts table selector 0 with the CiA 301 rates
//! ([`crate::wire::lss::bit_rate_kbit_per_s`]: not the reserved index 5 nor automatic
//! detection, 9); anything else is answered with error 1. Activate bit timing makes the
//! pending bit timing active and reports the switch delay: a real device waits that delay,
//! switches its controller and stays silent for the delay again ([`LssEvent::ActivateBitTiming`]).
//!
//! **Inquire node-ID** answers the active node-ID (0xFF while non-configured), as CANopenNode
//! does; a pending one is not reported before it is active.
//!
//! **Fastscan** (cs 0x51): see [`fastscan`]; only a non-configured slave in waiting state
//! takes part.
//!
//! Frames on other COB-IDs, remote frames, extended identifiers and payloads the codec
//! refuses ([`crate::wire::lss::LssParseError`]) are ignored: no answer, no change.

mod fastscan;

use crate::frame::CanFrame;
use crate::wire::lss::{
    bit_rate_kbit_per_s, error, IdentifyField, IdentityPart, LssMode, LssRequest, LssResponse,
    LSS_REQUEST, UNCONFIGURED_NODE_ID,
};
use fastscan::{FastscanState, Reply};

/// The 128-bit LSS address: the identity object 0x1018 sub 1..=4.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct LssIdentity {
    /// 0x1018:1.
    pub vendor_id: u32,
    /// 0x1018:2.
    pub product_code: u32,
    /// 0x1018:3.
    pub revision_number: u32,
    /// 0x1018:4.
    pub serial_number: u32,
}

impl LssIdentity {
    /// One part of the address.
    pub fn part(&self, p: IdentityPart) -> u32 {
        match p {
            IdentityPart::VendorId => self.vendor_id,
            IdentityPart::ProductCode => self.product_code,
            IdentityPart::RevisionNumber => self.revision_number,
            IdentityPart::SerialNumber => self.serial_number,
        }
    }
}

/// The LSS state of a slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssState {
    /// Waiting: only switch and identification services.
    Waiting,
    /// Configuration: configure, store and inquire services.
    Configuration,
}

/// What the node or the emulator must act on after a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssEvent {
    /// The slave entered LSS configuration state (global or selective switch, fastscan).
    ConfigurationState,
    /// The slave went back to LSS waiting state; nothing else to do.
    WaitingState,
    /// The slave went back to LSS waiting state as a non-configured device with a pending
    /// node-ID: the node performs an NMT reset communication now and boots with `node_id`
    /// (the slave's active node-ID is already `node_id` when this is reported).
    ResetCommunication {
        /// The node-ID to boot with, 1..=127.
        node_id: u8,
    },
    /// Configure node-ID accepted: the pending node-ID (`None`: 0xFF, unconfigure at the next
    /// reset communication).
    NodeIdConfigured {
        /// Pending node-ID.
        pending: Option<u8>,
    },
    /// Configure bit timing accepted: the pending bit timing (CiA 301 table index).
    BitTimingConfigured {
        /// Pending table index.
        table_index: u8,
    },
    /// Activate bit timing: switch the controller to `table_index` after `switch_delay_ms`
    /// and send nothing for `switch_delay_ms` after that (CiA 305). The slave's active bit
    /// timing is `table_index` from now on.
    ActivateBitTiming {
        /// The bit timing to switch to.
        table_index: u8,
        /// The switch delay, ms.
        switch_delay_ms: u16,
    },
    /// Store configuration: write these to non-volatile memory, then call
    /// [`LssSlave::store_done`] with the outcome (the master waits for the answer, python
    /// canopen 0.5 s).
    StoreRequested {
        /// Pending node-ID to store (`None`: 0xFF).
        node_id: Option<u8>,
        /// Pending bit timing to store.
        bit_timing_index: u8,
    },
}

/// The result of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LssOutput {
    /// Frame to send (COB-ID 0x7E4).
    pub response: Option<CanFrame>,
    /// What to act on.
    pub event: Option<LssEvent>,
}

impl LssOutput {
    const NONE: LssOutput = LssOutput {
        response: None,
        event: None,
    };

    fn respond(r: LssResponse) -> LssOutput {
        LssOutput {
            response: Some(r.to_frame()),
            event: None,
        }
    }

    fn event(e: LssEvent) -> LssOutput {
        LssOutput {
            response: None,
            event: Some(e),
        }
    }
}

/// Why a slave could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LssConfigError {
    /// Node-IDs are 1..=127 (`None` for non-configured).
    InvalidNodeId(u8),
    /// Not an index of the CiA 301 bit timing table this slave supports.
    UnsupportedBitTiming(u8),
}

impl core::fmt::Display for LssConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LssConfigError::InvalidNodeId(n) => {
                write!(f, "node-ID {n} is outside 1..=127 (255: non-configured)")
            }
            LssConfigError::UnsupportedBitTiming(i) => write!(
                f,
                "bit timing index {i} is not a CiA 301 bit rate (0..=4, 6..=8)"
            ),
        }
    }
}

impl std::error::Error for LssConfigError {}

/// Where a slave is in a multi-frame sequence: the position of the frame it expects next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sequence {
    None,
    /// Switch state selective: the next part (1..=3).
    Selective(u8),
    /// Identify remote slave: the next field (1..=5).
    Identify(u8),
}

/// An LSS slave.
#[derive(Clone, Debug)]
pub struct LssSlave {
    identity: LssIdentity,
    state: LssState,
    active_node_id: Option<u8>,
    pending_node_id: Option<u8>,
    stored_node_id: Option<u8>,
    active_bit_timing: u8,
    pending_bit_timing: u8,
    stored_bit_timing: u8,
    sequence: Sequence,
    fastscan: FastscanState,
    store_supported: bool,
    /// A store asked for and not yet answered: the values it writes.
    store_pending: Option<(Option<u8>, u8)>,
}

fn valid_node_id(n: u8) -> bool {
    (1..=127).contains(&n) || n == UNCONFIGURED_NODE_ID
}

fn node_id_option(n: u8) -> Option<u8> {
    (n != UNCONFIGURED_NODE_ID).then_some(n)
}

impl LssSlave {
    /// A slave at power-on with what its non-volatile memory holds: `node_id` (`None`:
    /// non-configured, 0xFF) and the bit timing (CiA 301 table index, 0 = 1 Mbit/s, 2 = 500
    /// kbit/s, ...). State waiting; store supported.
    pub fn new(
        identity: LssIdentity,
        node_id: Option<u8>,
        bit_timing_index: u8,
    ) -> Result<LssSlave, LssConfigError> {
        if let Some(n) = node_id {
            if !(1..=127).contains(&n) {
                return Err(LssConfigError::InvalidNodeId(n));
            }
        }
        if bit_rate_kbit_per_s(bit_timing_index).is_none() {
            return Err(LssConfigError::UnsupportedBitTiming(bit_timing_index));
        }
        Ok(LssSlave {
            identity,
            state: LssState::Waiting,
            active_node_id: node_id,
            pending_node_id: node_id,
            stored_node_id: node_id,
            active_bit_timing: bit_timing_index,
            pending_bit_timing: bit_timing_index,
            stored_bit_timing: bit_timing_index,
            sequence: Sequence::None,
            fastscan: FastscanState::default(),
            store_supported: true,
            store_pending: None,
        })
    }

    /// Whether store configuration is supported (default yes); without, it is answered with
    /// error 1.
    pub fn set_store_supported(&mut self, supported: bool) {
        self.store_supported = supported;
    }

    /// Handle one received frame: LSS requests on 0x7E5 (data frames, 11-bit identifier);
    /// anything else gives no response and no event.
    pub fn handle(&mut self, frame: &CanFrame) -> LssOutput {
        if frame.id != LSS_REQUEST || frame.rtr || frame.extended {
            return LssOutput::NONE;
        }
        match LssRequest::parse(frame.payload()) {
            Ok(req) => self.request(&req),
            Err(_) => LssOutput::NONE,
        }
    }

    /// Handle one parsed request (what [`LssSlave::handle`] does after the codec).
    pub fn request(&mut self, req: &LssRequest) -> LssOutput {
        let configuring = self.state == LssState::Configuration;
        match *req {
            LssRequest::SwitchStateGlobal(mode) => self.switch_global(mode),
            LssRequest::SwitchStateSelective { part, value } if !configuring => {
                self.switch_selective(part, value)
            }
            LssRequest::IdentifyRemoteSlave { field, value } => self.identify(field, value),
            LssRequest::IdentifyNonConfiguredRemoteSlave if self.non_configured() => {
                LssOutput::respond(LssResponse::IdentifyNonConfiguredSlave)
            }
            LssRequest::Fastscan(f) if !configuring && self.non_configured() => {
                match self.fastscan.request(&self.identity, &f) {
                    Reply::Silent => LssOutput::NONE,
                    Reply::Answer => LssOutput::respond(LssResponse::IdentifySlave),
                    Reply::AnswerSelected => {
                        self.enter(LssState::Configuration);
                        LssOutput {
                            response: Some(LssResponse::IdentifySlave.to_frame()),
                            event: Some(LssEvent::ConfigurationState),
                        }
                    }
                }
            }
            _ if configuring => self.configure(req),
            _ => LssOutput::NONE,
        }
    }

    /// The services of the configuration state.
    fn configure(&mut self, req: &LssRequest) -> LssOutput {
        match *req {
            LssRequest::ConfigureNodeId { node_id } => {
                if !valid_node_id(node_id) {
                    return LssOutput::respond(LssResponse::ConfigureNodeId {
                        error: error::NODE_ID_OUT_OF_RANGE,
                        spec_error: 0,
                    });
                }
                self.pending_node_id = node_id_option(node_id);
                LssOutput {
                    response: Some(
                        LssResponse::ConfigureNodeId {
                            error: error::OK,
                            spec_error: 0,
                        }
                        .to_frame(),
                    ),
                    event: Some(LssEvent::NodeIdConfigured {
                        pending: self.pending_node_id,
                    }),
                }
            }
            LssRequest::ConfigureBitTiming {
                table_selector,
                table_index,
            } => {
                if table_selector != 0 || bit_rate_kbit_per_s(table_index).is_none() {
                    return LssOutput::respond(LssResponse::ConfigureBitTiming {
                        error: error::BIT_TIMING_NOT_SUPPORTED,
                        spec_error: 0,
                    });
                }
                self.pending_bit_timing = table_index;
                LssOutput {
                    response: Some(
                        LssResponse::ConfigureBitTiming {
                            error: error::OK,
                            spec_error: 0,
                        }
                        .to_frame(),
                    ),
                    event: Some(LssEvent::BitTimingConfigured { table_index }),
                }
            }
            LssRequest::ActivateBitTiming { switch_delay_ms } => {
                self.active_bit_timing = self.pending_bit_timing;
                LssOutput::event(LssEvent::ActivateBitTiming {
                    table_index: self.active_bit_timing,
                    switch_delay_ms,
                })
            }
            LssRequest::StoreConfiguration => {
                if !self.store_supported {
                    return LssOutput::respond(LssResponse::StoreConfiguration {
                        error: error::STORE_NOT_SUPPORTED,
                        spec_error: 0,
                    });
                }
                let what = (self.pending_node_id, self.pending_bit_timing);
                self.store_pending = Some(what);
                LssOutput::event(LssEvent::StoreRequested {
                    node_id: what.0,
                    bit_timing_index: what.1,
                })
            }
            LssRequest::InquireIdentity(part) => LssOutput::respond(LssResponse::Identity {
                part,
                value: self.identity.part(part),
            }),
            LssRequest::InquireNodeId => LssOutput::respond(LssResponse::NodeId {
                node_id: self.active_node_id.unwrap_or(UNCONFIGURED_NODE_ID),
            }),
            _ => LssOutput::NONE,
        }
    }

    fn enter(&mut self, state: LssState) {
        self.state = state;
        self.sequence = Sequence::None;
        self.fastscan.restart();
    }

    fn switch_global(&mut self, mode: LssMode) -> LssOutput {
        let was = self.state;
        match mode {
            LssMode::Configuration => {
                self.enter(LssState::Configuration);
                if was == LssState::Configuration {
                    return LssOutput::NONE;
                }
                LssOutput::event(LssEvent::ConfigurationState)
            }
            LssMode::Waiting => {
                self.enter(LssState::Waiting);
                if was == LssState::Waiting {
                    return LssOutput::NONE;
                }
                match (self.active_node_id, self.pending_node_id) {
                    (None, Some(node_id)) => {
                        self.reset_communication();
                        LssOutput::event(LssEvent::ResetCommunication { node_id })
                    }
                    _ => LssOutput::event(LssEvent::WaitingState),
                }
            }
        }
    }

    fn switch_selective(&mut self, part: IdentityPart, value: u32) -> LssOutput {
        let i = part.index();
        let in_order = i == 0 || self.sequence == Sequence::Selective(i);
        self.sequence = Sequence::None;
        if !in_order || value != self.identity.part(part) {
            return LssOutput::NONE;
        }
        if part != IdentityPart::SerialNumber {
            self.sequence = Sequence::Selective(i + 1);
            return LssOutput::NONE;
        }
        self.enter(LssState::Configuration);
        LssOutput {
            response: Some(LssResponse::SwitchStateSelective.to_frame()),
            event: Some(LssEvent::ConfigurationState),
        }
    }

    fn identify(&mut self, field: IdentifyField, value: u32) -> LssOutput {
        let i = field.index();
        let in_order = i == 0 || self.sequence == Sequence::Identify(i);
        self.sequence = Sequence::None;
        let id = &self.identity;
        let matches = match field {
            IdentifyField::VendorId => value == id.vendor_id,
            IdentifyField::ProductCode => value == id.product_code,
            IdentifyField::RevisionLow => value <= id.revision_number,
            IdentifyField::RevisionHigh => value >= id.revision_number,
            IdentifyField::SerialLow => value <= id.serial_number,
            IdentifyField::SerialHigh => value >= id.serial_number,
        };
        if !in_order || !matches {
            return LssOutput::NONE;
        }
        if field != IdentifyField::SerialHigh {
            self.sequence = Sequence::Identify(i + 1);
            return LssOutput::NONE;
        }
        LssOutput::respond(LssResponse::IdentifySlave)
    }

    fn non_configured(&self) -> bool {
        self.active_node_id.is_none() && self.pending_node_id.is_none()
    }

    /// The outcome of a store ([`LssEvent::StoreRequested`]): `stored` true makes the values
    /// asked for the stored ones (what [`LssSlave::reset_node`] loads) and answers error 0;
    /// false answers error 2 (storage medium access failed). `None` when no store is waiting
    /// for its answer.
    pub fn store_done(&mut self, stored: bool) -> Option<CanFrame> {
        let (node_id, bit_timing) = self.store_pending.take()?;
        let error = if stored {
            self.stored_node_id = node_id;
            self.stored_bit_timing = bit_timing;
            error::OK
        } else {
            error::STORE_ACCESS_FAILED
        };
        Some(
            LssResponse::StoreConfiguration {
                error,
                spec_error: 0,
            }
            .to_frame(),
        )
    }

    /// NMT reset communication: the pending node-ID and bit timing become active, the slave
    /// is in waiting state with no sequence or scan under way.
    pub fn reset_communication(&mut self) {
        self.enter(LssState::Waiting);
        self.active_node_id = self.pending_node_id;
        self.active_bit_timing = self.pending_bit_timing;
    }

    /// NMT reset node (an application restart): the stored node-ID and bit timing are loaded
    /// as pending, then as [`LssSlave::reset_communication`]. A store not yet answered is
    /// dropped.
    pub fn reset_node(&mut self) {
        self.store_pending = None;
        self.pending_node_id = self.stored_node_id;
        self.pending_bit_timing = self.stored_bit_timing;
        self.reset_communication();
    }

    /// The LSS address.
    pub fn identity(&self) -> LssIdentity {
        self.identity
    }
    /// LSS state.
    pub fn state(&self) -> LssState {
        self.state
    }
    /// Active node-ID (`None`: non-configured).
    pub fn active_node_id(&self) -> Option<u8> {
        self.active_node_id
    }
    /// Pending node-ID: active after the next NMT reset communication.
    pub fn pending_node_id(&self) -> Option<u8> {
        self.pending_node_id
    }
    /// Stored node-ID: pending after the next NMT reset node or power-on.
    pub fn stored_node_id(&self) -> Option<u8> {
        self.stored_node_id
    }
    /// Active bit timing (CiA 301 table index).
    pub fn active_bit_timing(&self) -> u8 {
        self.active_bit_timing
    }
    /// Pending bit timing.
    pub fn pending_bit_timing(&self) -> u8 {
        self.pending_bit_timing
    }
    /// Stored bit timing.
    pub fn stored_bit_timing(&self) -> u8 {
        self.stored_bit_timing
    }
    /// Whether a store configuration waits for [`LssSlave::store_done`].
    pub fn store_pending(&self) -> bool {
        self.store_pending.is_some()
    }
}
