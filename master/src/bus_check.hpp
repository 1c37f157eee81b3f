// Checks, before the bus is opened, that this process can receive on it: LCM (1.3.1) reports a
// receive socket it cannot bind only as "bind: Address already in use" on stderr and then hears
// nothing, so a run would fail much later as participants that "do not answer".
#pragma once

#include <string>

namespace master {

// For a udpm:// URL: binds a UDP socket to its port the way LCM does (SO_REUSEADDR, any
// address) and closes it again; raises cosim::LinkError naming the URL, the port and the cause
// when that fails (another program holds the port without sharing it). Other URLs: nothing.
void check_bus_can_bind(const std::string& url);

}  // namespace master
