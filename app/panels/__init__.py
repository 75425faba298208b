"""The workbench's panels, one module each; they talk through WorkbenchState's named events."""
