/**
 * Layer: React glue for tag names (read-only): the robot's names of its I/O points and bit
 * registers, keyed `name.index` (0-based, docs/api.md "Tag names"), for the lamps and toggles
 * that show them beside the spec's label. The panel fills it from its tag-names view, the kiosk
 * from a plain GET (lib/layout/tagNames.ts); empty until then.
 */
import { createContext, useContext } from "react";
import type { TagNames } from "../lib/layout/tags";

export const TagNamesContext = createContext<TagNames>({});

export function useTagNames(): TagNames {
  return useContext(TagNamesContext);
}
