// ssdo options: the frame options of the table (frame_options.h), as text or as the
// Markdown reference committed as docs/options.md.
#include <iostream>
#include <memory>

#include <CLI/CLI.hpp>

#include "service/commands.h"
#include "service/frame_options.h"

namespace ssdo {

Command register_options(CLI::App& app) {
  auto markdown = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "options", "List the frame options: the flags of process, serve and client, which are also the keys of "
                 "--config files and of socket requests");
  cmd->add_flag("--markdown", *markdown, "Print the reference docs/options.md");
  return {cmd, [markdown] {
            if (*markdown) {
              std::cout << frame_options_markdown();
              return 0;
            }
            for (const FrameOption& o : frame_options()) {
              std::cout << "--" << o.name;
              if (o.kind == OptionKind::number || o.kind == OptionKind::integer) std::cout << " " << describe_range(o);
              std::cout << "\n    " << o.help << "\n";
            }
            return 0;
          }};
}

}  // namespace ssdo
