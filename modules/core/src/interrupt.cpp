#include "rgbdt/core/interrupt.hpp"

#include <csignal>

#include "rgbdt/core/output.hpp"

namespace rgbdt::core {
namespace {

volatile std::sig_atomic_t g_signal = 0;

extern "C" void on_interrupt(int sig) {
  if (g_signal != 0) {
    // A second Ctrl-C: the user wants out now. Temporaries being written are removed first,
    // so the output folder holds only whole files.
    remove_unfinished_outputs();
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_signal = sig;
}

}  // namespace

void install_interrupt_handler() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool interrupted() { return g_signal != 0; }

int interrupt_signal() { return static_cast<int>(g_signal); }

}  // namespace rgbdt::core
