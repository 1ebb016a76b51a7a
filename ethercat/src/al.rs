//! The application-layer state machine (ETG.1000.6 6.4.1): INIT, PRE-OP (mailbox), SAFE-OP
//! (inputs valid), OP (outputs valid), BOOT. A request comes through AL control (0x0120);
//! the slave answers in AL status (0x0130, bit 4 = error indication) and AL status code
//! (0x0134). A refused transition leaves the slave in its state with the error flag and the
//! code; while the flag stands, only a request with the acknowledge bit (0x10) is heard.

/// AL states (the values of AL control / AL status bits 0-3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum AlState {
    /// INIT.
    Init = 1,
    /// PRE-OPERATIONAL: mailbox.
    PreOp = 2,
    /// BOOTSTRAP.
    Boot = 3,
    /// SAFE-OPERATIONAL: inputs.
    SafeOp = 4,
    /// OPERATIONAL: outputs.
    Op = 8,
}

impl AlState {
    /// From AL control bits 0-3.
    pub fn from_u8(v: u8) -> Option<AlState> {
        Some(match v & 0x0F {
            1 => AlState::Init,
            2 => AlState::PreOp,
            3 => AlState::Boot,
            4 => AlState::SafeOp,
            8 => AlState::Op,
            _ => return None,
        })
    }
}

/// AL status codes (ETG.1000.6 table 11).
pub mod code {
    /// No error.
    pub const NONE: u16 = 0x0000;
    /// Unspecified error.
    pub const UNSPECIFIED: u16 = 0x0001;
    /// Invalid requested state change.
    pub const INVALID_STATE_CHANGE: u16 = 0x0011;
    /// Unknown requested state.
    pub const UNKNOWN_STATE: u16 = 0x0012;
    /// Bootstrap not supported.
    pub const BOOT_NOT_SUPPORTED: u16 = 0x0013;
    /// Invalid mailbox configuration (PRE-OP).
    pub const INVALID_MAILBOX_CONFIG: u16 = 0x0016;
    /// Invalid sync manager configuration.
    pub const INVALID_SM_CONFIG: u16 = 0x0017;
    /// Sync manager watchdog.
    pub const SM_WATCHDOG: u16 = 0x001B;
    /// Invalid output configuration.
    pub const INVALID_OUTPUT_CONFIG: u16 = 0x001D;
    /// Invalid input configuration.
    pub const INVALID_INPUT_CONFIG: u16 = 0x001E;
}

/// The state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Al {
    /// Current state.
    pub state: AlState,
    /// Error indication (AL status bit 4).
    pub error: bool,
    /// AL status code.
    pub code: u16,
}

impl Default for Al {
    fn default() -> Self {
        Al {
            state: AlState::Init,
            error: false,
            code: code::NONE,
        }
    }
}

/// What the slave checks at a transition; each returns the AL status code of a refusal.
pub trait Checks {
    /// INIT -> PRE-OP: the mailbox sync managers as the SII says.
    fn mailbox(&mut self) -> Result<(), u16>;
    /// PRE-OP -> SAFE-OP: the process-data sync managers, PDO assignment and mapping.
    fn process_data(&mut self) -> Result<(), u16>;
    /// SAFE-OP -> OP: outputs valid.
    fn outputs(&mut self) -> Result<(), u16>;
    /// Entered a state (the slave starts or stops what it runs there).
    fn entered(&mut self, state: AlState);
}

impl Al {
    /// AL status register value.
    pub fn status(&self) -> u16 {
        self.state as u16 | if self.error { 0x10 } else { 0 }
    }

    /// A write to AL control with `value`.
    pub fn request(&mut self, value: u16, checks: &mut impl Checks) {
        let ack = value & 0x10 != 0;
        if self.error && !ack {
            return;
        }
        if ack {
            self.error = false;
            self.code = code::NONE;
        }
        let Some(target) = AlState::from_u8(value as u8) else {
            self.refuse(code::UNKNOWN_STATE);
            return;
        };
        if target == self.state {
            return;
        }
        use AlState::*;
        let step = match (self.state, target) {
            (_, Init) => Ok(()),
            (Init, PreOp) => checks.mailbox(),
            (Init, Boot) => Ok(()),
            (PreOp, SafeOp) => checks.process_data(),
            (SafeOp, Op) => checks.outputs(),
            (Op, SafeOp) | (Op, PreOp) | (SafeOp, PreOp) => Ok(()),
            _ => Err(code::INVALID_STATE_CHANGE),
        };
        match step {
            Ok(()) => {
                self.state = target;
                checks.entered(target);
            }
            Err(c) => self.refuse(c),
        }
    }

    /// Refuse: stay, flag the error with `c`.
    pub fn refuse(&mut self, c: u16) {
        self.error = true;
        self.code = c;
    }

    /// A local error (watchdog, say) takes the slave down to `to` with code `c`.
    pub fn fall_to(&mut self, to: AlState, c: u16, checks: &mut impl Checks) {
        self.state = to;
        self.refuse(c);
        checks.entered(to);
    }
}
