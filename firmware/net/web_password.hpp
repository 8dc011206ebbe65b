#pragma once
// The console's `web password`: the web page's password, kept in the configuration as its hash
// only (web.password), the page's own row on the console.
#include <functional>

#include "firmware/console/console.hpp"
#include "hal/password.hpp"

namespace calbox::firmware {

// `config_changed` puts the configuration in force, as after `config set`.
ConsoleCommand web_password_row(Configuration& config, hal::PasswordHasher& passwords,
                                std::function<void()> config_changed);

}  // namespace calbox::firmware
