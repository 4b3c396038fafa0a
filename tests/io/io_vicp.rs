//! VICP client against the mock_lab VICP server, over real loopback sockets.

use crate::io_support;

loopback_suite!(io_support::Proto::Vicp);
