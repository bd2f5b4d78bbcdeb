// Enumerations named by a table: one {value, name} array per enum gives both directions
// (to_string and parse), so a value's name is written once.
#pragma once

#include <optional>
#include <span>
#include <string_view>
#include <utility>

namespace ssdo {

template <class E>
using EnumNames = std::span<const std::pair<E, std::string_view>>;

// The name of `value` in `names`, "?" when the table does not hold it.
template <class E>
constexpr std::string_view enum_name(EnumNames<E> names, E value) {
  for (const auto& [v, name] : names)
    if (v == value) return name;
  return "?";
}

// The value named `name` in `names`, none when no entry has that name.
template <class E>
constexpr std::optional<E> parse_enum(EnumNames<E> names, std::string_view name) {
  for (const auto& [v, n] : names)
    if (n == name) return v;
  return std::nullopt;
}

}  // namespace ssdo
