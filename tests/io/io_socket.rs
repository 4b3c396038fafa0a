//! Raw socket client against the mock_lab raw-socket server, over real loopback sockets.

use crate::io_support;

loopback_suite!(io_support::Proto::Socket);
