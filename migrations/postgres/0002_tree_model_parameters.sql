-- The reconstruction record (models.parameters) of a tree's current model,
-- kept on the tree row like its metrics, so that tree documents and listings
-- read it without a second query or a join (in SQLite the parameters column
-- sits behind the skeleton, LsJSON and chain code of the model row, so even
-- a join would read those large values page by page).
ALTER TABLE trees ADD COLUMN model_parameters TEXT;
UPDATE trees SET model_parameters =
    (SELECT parameters FROM models WHERE models.id = trees.model_id)
WHERE model_id IS NOT NULL;
