#pragma once
/// \file
/// Ctrl-C for long-running apps: the first SIGINT or SIGTERM only raises a flag that the
/// app polls between units of work (a cloud, a view), so it can stop cleanly, keep what is
/// complete and say so. A second signal ends the process at once, after removing the
/// temporary files of outputs still being written (core::remove_unfinished_outputs).

namespace rgbdt::core {

/// Installs the handlers for SIGINT and SIGTERM (idempotent).
void install_interrupt_handler();

/// True once SIGINT or SIGTERM has arrived after install_interrupt_handler().
bool interrupted();

/// The signal number that arrived (0 if none).
int interrupt_signal();

}  // namespace rgbdt::core
