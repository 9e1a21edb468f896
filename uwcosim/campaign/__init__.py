"""Monte Carlo campaigns: scenarios x variants x seeded runs, on local processes or Dask."""

from uwcosim.campaign.spec import CampaignSpec, load_campaign

__all__ = ["CampaignSpec", "load_campaign"]
